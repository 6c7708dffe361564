"""Identification of an as-built unit from its test recording: `Recording`, `read_recording`
(`tolerax.identification.recording`) and `identify`, `Identification`, `synthetic_recording`
(`tolerax.identification.identify`)."""
