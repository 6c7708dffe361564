"""The identification notebook (one built unit: its recording, its identified scene, its
end-of-life pointing) executes end to end at its small size; it is also the default tier's test
that a unit's backlash is recovered inside its interval from a noisy, quantised recording. Its own file, collected last
(tests/conftest.py): its identification is test_identify.py's default test's program and its life
notebooks/mission_life.ipynb's, both read back from the run's cache by then."""

import math

from _notebooks import execute as _execute, number as _number

import tolerax as tx


def test_identify_unit_notebook_executes(monkeypatch, tmp_path):
    """Small size: the ring backlash alone from the scene's value, one life point. The recording
    written as the test stand's CSV and read back, a bad one refused with its reason, the truth
    inside the 95 % interval with the residual the encoder's (noise and rounding: 2.64 µrad, to
    30 % as test_identify.py's), the identified unit written as a scene file that builds with the
    estimate, and its life on the full stage run beside the drawing's nominal unit."""
    monkeypatch.setenv("TOLERAX_OUT", str(tmp_path))
    outputs = "".join(_execute(monkeypatch, "identify_unit.ipynb", "TOLERAX_IDENTIFY_SIZE"))
    assert "small {" in outputs and "unit7.csv: 141 samples over 0.35 s" in outputs
    assert "refused:" in outputs and "repeats the time of the sample before" in outputs
    assert "azimuth.ring_backlash: truth 60.00 µm, inside its 95 % interval" in outputs
    # ... and the interval checked along its profile: the lost motion's cost is quadratic there.
    assert "-> the interval holds" in outputs and "DOES NOT HOLD" not in outputs
    # The lost motion at the reversal sees the backlash directly: an interval a few tenths of a µm wide.
    lo = _number(r"\| azimuth.ring_backlash \| [\d.]+ µm \| ([\d.]+) µm – [\d.]+ µm \| [\d.e+-]+ \| determined \|", outputs)
    hi = _number(r"\| azimuth.ring_backlash \| [\d.]+ µm \| [\d.]+ µm – ([\d.]+) µm \| [\d.e+-]+ \| determined \|", outputs)
    assert 0.0 < hi - lo < 2.0, (lo, hi)
    assert _number(r"residual ([\d.]+) µrad against the encoder's", outputs) < 1.3 * math.hypot(2.0, 6.0 / math.sqrt(12))
    unit = tx.load_scene(str(tmp_path / "identified_planetary.toml")).build()
    from tolerax.design.features import design_names, design_of

    backlash = 1e6 * float(design_of(unit)[design_names(unit).index("azimuth.ring_backlash")])
    assert abs(backlash - 60.0) < 0.5 and unit.azimuth.stage.contact_names  # the full stage, with the estimate
    rms = [_number(rf"{label} +ring backlash +[\d.]+ um: RMS pointing +([\d.]+) arcsec as built", outputs)
           for label in ("drawing's nominal", "identified unit")]
    assert all(r > 0 for r in rms) and "a life point's run failed" not in outputs
