"""Identification of an as-built unit from its test recording: `Recording`, `read_recording`
(`tolerax.identify.recording`) and `identify`, `Identification`, `synthetic_recording`
(`tolerax.identify.identify`)."""
