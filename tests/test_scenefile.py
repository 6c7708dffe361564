"""Scene files (src/tolerax/_scenefile.py, docs/scene_files.md) and `tolerax run`."""

import inspect
import json
import math
import pathlib
import re
import textwrap

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax import cli, studies as S
from tolerax.io import schema


def _same_model(a, b, rtol=0.0):
    """Same structure (tree definition, static fields included) and the same leaves."""
    la, ta = jax.tree.flatten(eqx.filter(a, eqx.is_array))
    lb, tb = jax.tree.flatten(eqx.filter(b, eqx.is_array))
    assert ta == tb
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(la, lb):
        assert np.shape(x) == np.shape(y)
        if rtol == 0.0:
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
        else:
            np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=rtol, atol=0.0)


# --------------------------------------------------------------------------------------------
# Round trips and the built-in scenes


@pytest.mark.parametrize("name", tx.builtin_scenes())
def test_builtin_round_trip(name, tmp_path):
    first = tx.load_scene(name)
    path = tx.save_scene(first, tmp_path / f"{name}.toml")
    second = tx.load_scene(path)
    assert second == first
    assert second.data == first.data
    assert second.to_toml() == first.to_toml()  # saving is idempotent
    _same_model(second.build(), first.build())


def test_builtins_cover_the_paper_and_design_scenes():
    names = set(tx.builtin_scenes())
    assert {"scan", "scan-azimuth", "scan-pitch", "scan-azimuth-planetary", "scan-azimuth-fast", "paper-table2"} <= names
    for table in ("table3", "table6", "table7"):
        assert sum(n.startswith(f"paper-{table}-") for n in names) == 6


_STUDY_FILES = {  # study of tolerax.studies -> (label -> built-in name)
    "radial_clearance": lambda lab: f"paper-table3-{lab['mode']}-{lab['case']}",
    "backlash": lambda lab: f"paper-table6-{lab['mode']}-b{lab['backlash']}",
    "coupling": lambda lab: f"paper-table7-{lab['mode']}-{lab['case']}",
}


@pytest.mark.parametrize("study", list(_STUDY_FILES))
def test_paper_scenes_are_the_studies_scenes(study):
    """The paper's Tables 3, 6, 7 as files build the models of `tolerax studies` (full size)."""
    full = S.SIZES["full"]
    cases = S.scenes(study, "full")
    assert len(cases) == 6
    for labels, mech in cases:
        scene_file = tx.load_scene(_STUDY_FILES[study](labels))
        # The studies write clearances as n * 1e-6 (100 * 1e-6 = 9.999999999999999e-05), the files
        # as decimal literals (1e-04): the same numbers to one ulp, so compare to 1e-14.
        _same_model(scene_file.build(), mech, rtol=1e-14)
        run = scene_file.run
        assert (run["duration"], run["settle"], run["n_save"], run["start"]) == (full.duration, full.settle, full.n_save, "steady")


def test_table2_and_design_scenes_are_the_builder_calls():
    law = tx.AdamsImpact()  # its defaults are the paper's Table 2 K = 1e7 N/m, D = 100 N s/m
    expected = tx.antenna("dual", fidelity="planetary", drive="torque", base="free",
                          azimuth_stage=tx.default_stage(contact_law=law), pitch_stage=tx.default_stage(contact_law=law))
    _same_model(tx.load_scene("paper-table2").build(), expected)
    _same_model(tx.load_scene("scan").build(), tx.scan())
    _same_model(tx.load_scene("scan-azimuth").build(), tx.scan("azimuth", fidelity=("lumped", "ideal")))
    _same_model(tx.load_scene("scan-pitch").build(), tx.scan("pitch", fidelity=("ideal", "lumped")))
    _same_model(tx.load_scene("scan-azimuth-planetary").build(), tx.scan("azimuth", fidelity=("planetary", "ideal")))
    fast = tx.load_scene("scan-azimuth-fast")
    _same_model(fast.build(), tx.scan("azimuth", fidelity=("planetary-scaled", "ideal"), mass_scaling=1000.0))
    assert (fast.run["rtol"], fast.run["atol"], fast.run["pcoeff"], fast.run["icoeff"]) == (1e-3, 1e-6, 0.3, 0.3)


def test_every_key_is_documented():
    doc = (pathlib.Path(__file__).parents[1] / "docs" / "scene_files.md").read_text()
    keys = set(schema.TOP_KEYS) | set(schema.RUN_KEYS) | set(schema.OUTPUT_KEYS) | set(schema.TOLERANCE_KEYS) | set(schema.SERIES) | set(schema.PLOTS)
    keys |= set(schema.LIFE_KEYS)
    for builder in schema.BUILDERS.values():
        keys |= set(inspect.signature(builder).parameters)
    keys |= set(inspect.signature(tx.default_stage).parameters)
    for cls in schema.CONTACT_LAWS.values():
        keys |= set(inspect.signature(cls.__init__).parameters) - {"self"}
    keys |= set(schema.CONTACT_LAWS) | {"kind", "law"}
    for cls in schema.STRUCTURE_KEYS.values():
        keys |= set(inspect.signature(cls.__init__).parameters) - {"self"}
    missing = sorted(k for k in keys if f"`{k}`" not in doc)
    assert not missing, f"undocumented scene-file keys: {missing}"
    for name in tx.builtin_scenes():
        stem = re.sub(r"-(a|b|c|b\d+)$", "", name).replace("-azimuth", "-{azimuth,pitch}").replace("-pitch", "-{azimuth,pitch}")
        assert f"`{name}`" in doc or stem in doc, name


# --------------------------------------------------------------------------------------------
# The writer


def test_writer_round_trips_awkward_values():
    data = {
        "title": 'quotes " and \\ backslash, a tab\t, é, a newline\n, DEL \x7f, \U0001f600',
        "scene": {"kind": "scan", "mode": "azimuth", "fidelity": ["lumped", "ideal"], "amplitude": 5e-324,
                  "azimuth_stage": {"sun_teeth": 18, "ring_teeth": 72, "planet_teeth": 27, "dynamic_backlash": False,
                                    "backlash": 1.0000000000000002e-05, "mesh_stiffness": 1e300}},
        "run": {"duration": 0.1, "rtol": 1e-7},
        "tolerances": {"band": 0.0, "bands": {"azimuth.carrier_clearance": 2.5e-06}},
    }
    scene_file = tx.SceneFile.from_data(data)
    again = tx.parse_scene(scene_file.to_toml())
    assert again == scene_file
    assert again.data == data
    assert type(again.data["scene"]["azimuth_stage"]["sun_teeth"]) is int
    tol = again.tolerances()
    bands = dict(zip(tol.names, np.asarray(tol.band)))
    assert bands["azimuth.carrier_clearance"] == 2.5e-06
    assert all(v == 0.0 for n, v in bands.items() if n != "azimuth.carrier_clearance")


def test_replace_and_objective():
    scene_file = tx.load_scene("scan-azimuth")
    short = scene_file.replace(duration=0.1, settle=0.0)
    assert short.run["duration"] == 0.1 and short != scene_file
    objective = short.objective()
    assert (objective.duration, objective.settle, objective.start, objective.n_save) == (0.1, 0.0, "steady", 101)
    with pytest.raises(tx.SceneFileError, match=r"\[run\] settle: .*settle < duration"):
        scene_file.replace(duration=0.1)
    # The step-size controller's coefficients reach the objective (and `simulate`, which checks them).
    pi = short.replace(pcoeff=0.3, icoeff=0.3)
    assert (pi.objective().pcoeff, pi.objective().icoeff) == (0.3, 0.3)
    assert (objective.pcoeff, objective.icoeff) == (0.0, 1.0)  # the default: the I-controller
    # The solver by name, from [run] to the objective; an unknown name is refused naming the key.
    assert objective.solver == "Tsit5" and short.replace(solver="Bosh3").objective().solver == "Bosh3"
    # ... and it is what the objective's runs and the scene file's own run solve with.
    # (Each run below is a program of its own, ~7 s to compile: one run per setting. The file's
    # max_steps is the objective's budget, so its own run and the objective's are one program.)
    tiny = short.replace(duration=0.01, n_save=11, solver="Bosh3", max_steps=400_000)
    by_objective = tiny.objective().simulate_scene(tiny.build())
    by_simulate = tiny.simulate()  # tx.simulate(..., solver="Bosh3") with the file's other [run] keys
    assert int(by_objective.num_steps) == int(by_simulate.num_steps)
    assert by_objective.integrated_with.startswith("Bosh3, rtol 1e-06") and by_simulate.integrated_with.startswith("Bosh3")
    # The step limits too: a fixed step of 10 us (inside the lumped stage's stability limit) takes
    # the objective's 2 ms run through 200 steps (the adaptive Bosh3 run above took 10 ms in
    # fewer); the other limits reach the objective's integrator, which hands them to the run as
    # the fixed step is handed (`Integrator.options`).
    fixed = short.replace(duration=0.002, n_save=11, fixed_step=1e-5)
    assert fixed.objective().fixed_step == 1e-5
    assert int(fixed.objective().simulate_scene(fixed.build()).num_steps) == 200 > int(by_objective.num_steps)
    capped = short.replace(duration=0.002, n_save=11, dtmax=1e-5, dt0=1e-7, dtmin=1e-12).objective()
    assert (capped.dtmax, capped.dt0, capped.dtmin) == (1e-5, 1e-7, 1e-12)
    assert {k: capped.integrator.options()[k] for k in ("dtmax", "dt0", "dtmin")} == dict(dtmax=1e-5, dt0=1e-7, dtmin=1e-12)
    assert (objective.dt0, objective.dtmax, objective.fixed_step) == (1e-6, 1e-3, None)  # simulate's defaults
    # Every [run] key is an objective field of the same name carrying the file's value (a run
    # setting the file leaves out, None, is the automatic integrator's, ACCURATE, with the
    # objective's step budget).
    auto = tx.solve.ACCURATE.replace(max_steps=400_000).options()
    settings = [key for key in tx.io.schema.RUN_KEYS if key != "integrator"]  # the preset's name: the integrator below
    assert {key: getattr(objective, key) for key in settings} == {
        key: auto[key] if value is None and key in auto else value for key, value in short.run.items() if key in settings}
    assert objective.integrator == tx.solve.ACCURATE.replace(max_steps=400_000)
    assert "chosen automatically" in objective.integrated_with and "as asked" in tiny.objective().integrated_with
    with pytest.raises(tx.SceneFileError, match=r"\[run\] solver: solver 'Euler' is unknown"):
        short.replace(solver="Euler")
    with pytest.raises(ValueError, match="PointingObjective: solver 'Euler' is unknown"):
        tx.PointingObjective(short.build(), duration=0.1, settle=0.0, solver="Euler")


# --------------------------------------------------------------------------------------------
# Malformed files: the key, its table and its line


GOOD = """\
title = "a test scene"

[scene]
kind = "scan"
mode = "azimuth"
fidelity = ["lumped", "ideal"]

[scene.azimuth_stage]
sun_teeth = 20
planet_clearance = 5e-05

[run]
duration = 0.6
settle = 0.3
start = "steady"
"""


def _error(text) -> tx.SceneFileError:
    with pytest.raises(tx.SceneFileError) as info:
        tx.parse_scene(text, source="t.toml")
    return info.value


def test_good_text_parses():
    scene_file = tx.parse_scene(GOOD)
    assert float(scene_file.build().azimuth.stage.planet_support.bearing.clearance) == 5e-05


@pytest.mark.parametrize(
    "old, new, line, table, key, message",
    [
        ("planet_clearance = 5e-05", "planet_clearence = 5e-05", 10, "scene.azimuth_stage", "planet_clearence", "unknown key"),
        ('mode = "azimuth"', 'mode = "azimuth"\nrotor = 1', 6, "scene", "rotor", "unknown key"),
        ('start = "steady"', 'start = "steady"\nsolver = "Euler"', 16, "run", "solver", "solver 'Euler' is unknown"),
        ('title = "a test scene"', 'titel = "a test scene"', 1, "", "titel", "unknown key"),
        ("sun_teeth = 20", "sun_teeth = 20.0", 9, "scene.azimuth_stage", "sun_teeth", "must be an integer"),
        ("duration = 0.6", 'duration = "0.6"', 13, "run", "duration", "must be a number"),
        # A number with its unit typed in (a new user's "50um"): the file's units named.
        ("planet_clearance = 5e-05", 'planet_clearance = "50um"', 10, "scene.azimuth_stage", "planet_clearance",
         "must be a number, got '50um' (a string). Scene files hold plain numbers, each in its key's unit (docs/scene_files.md: "
         "lengths in m, so 50 µm is 5e-05"),
        ('fidelity = ["lumped", "ideal"]', "fidelity = 3", 6, "scene", "fidelity", "must be a string or a list of 2"),
        ("planet_clearance = 5e-05", "planet_clearance = -5e-05", 10, "scene.azimuth_stage", "planet_clearance", "must be finite and >= 0"),
        ('mode = "azimuth"', 'mode = "roll"', 5, "scene", "mode", "mode='roll' is unknown"),
        ('kind = "scan"', 'kind = "robot"', 4, "scene", "kind", "unknown scene kind"),
        ('start = "steady"', 'start = "moving"', 15, "run", "start", "is unknown"),
        ('start = "steady"', 'start = "steady"\nicoeff = 0.0', 16, "run", "icoeff", "must be a finite number > 0"),
        ('start = "steady"', 'start = "steady"\npcoeff = -0.1', 16, "run", "pcoeff", "must be a finite number >= 0"),
        ("settle = 0.3", "settle = 0.7", 14, "run", "settle", "settle < duration"),
        ('fidelity = ["lumped", "ideal"]', 'fidelity = "ideal"\nbase = "fixed"', 7, "scene", "base", "nothing to integrate"),
        # Inputs a newcomer gets wrong without a word otherwise: a module in the wrong unit, a
        # scan amplitude beside the profile that replaces it.
        ("sun_teeth = 20", "sun_teeth = 20\nmodule = 1e9", 10, "scene.azimuth_stage", "module", "ISO 54"),
        # A check of one key against another names the one it is about, at its line (issue 61:
        # a backlash typed in um was reported at the module's line).
        ("sun_teeth = 20", "module = 1e-3\nsun_teeth = 20\nbacklash = 80", 11, "scene.azimuth_stage", "backlash", "below the module"),
        ('mode = "azimuth"', 'mode = "azimuth"\namplitude = 0.01\nprofile_times = [0.0, 0.2]\nprofile_angles = [0.0, 0.01]', 6,
         "scene", "amplitude", "ignores 'amplitude'"),
    ],
)
def test_malformed_files_name_key_and_line(old, new, line, table, key, message):
    err = _error(GOOD.replace(old, new))
    assert (err.line, err.table, err.key) == (line, table, key)
    assert str(err).startswith(f"t.toml:{line}: ")
    assert key in str(err) and message in str(err)


def test_bad_toml_syntax_gives_the_line():
    err = _error(GOOD.replace("duration = 0.6", "duration = 0.6.1"))
    assert err.line == 13 and "invalid TOML" in str(err) and str(err).startswith("t.toml:13: ")


def test_missing_tables_and_keys():
    err = _error(GOOD.replace("duration = 0.6\n", ""))
    assert err.line == 12 and "missing key 'duration'" in str(err)
    err = _error(GOOD.split("[run]")[0])
    assert "missing table [run]" in str(err)


def test_tolerances_and_contact_law_are_checked():
    text = GOOD + '\n[tolerances]\nband = 1e-05\n\n[tolerances.bands]\n"azimuth.sun_clearance" = 1e-06\n'
    err = _error(text)  # a lumped joint models no sun clearance
    assert err.line == 21 and err.key == "azimuth.sun_clearance" and "azimuth.carrier_clearance" in str(err)
    text = GOOD.replace("sun_teeth = 20", 'sun_teeth = 20\n\n[scene.azimuth_stage.contact_law]\nlaw = "Hertz"')
    err = _error(text)
    assert (err.line, err.key) == (12, "law") and "BaiZhao" in str(err)
    text = GOOD.replace("planet_clearance = 5e-05", 'planet_clearance = 5e-05\n\n[scene.azimuth_stage.contact_law]\nlaw = "AdamsImpact"\nstiffness = -1.0')
    err = _error(text)  # the builder's own check, located at the key
    assert (err.line, err.key) == (14, "stiffness") and "AdamsImpact.stiffness must be" in str(err)


def test_line_of_other_key_styles():
    """Dotted keys and inline tables are found by their first `key =`."""
    text = textwrap.dedent("""\
        [scene]
        kind = "scan"
        azimuth_stage = { sun_teeth = 20, planet_clearence = 1e-05 }

        [run]
        duration = 0.6
        """)
    err = _error(text)
    assert (err.line, err.key) == (3, "planet_clearence")
    text = 'scene.kind = "scan"\nscene.fidelty = "lumped"\nrun.duration = 0.6\n'
    err = _error(text)
    assert (err.line, err.key) == (2, "fidelty")


def test_load_errors():
    with pytest.raises(tx.SceneFileError, match="no built-in scene 'nope'.*scan-azimuth"):
        tx.load_scene("nope")
    with pytest.raises(tx.SceneFileError, match="cannot read"):
        tx.load_scene("missing/dir/x.toml")


# --------------------------------------------------------------------------------------------
# The command line


def test_cli_rejects_bad_input(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(GOOD.replace("sun_teeth = 20", "sun_teeth = 20\nsun_teth = 20"))
    assert cli.main(["run", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:10: [scene.azimuth_stage] sun_teth: unknown key" in err
    assert not (tmp_path / "o").exists()
    assert cli.main(["run", "no-such-scene"]) == 2
    for argv in (["run", "scan", "--duration", "-1"], ["run", "scan", "--n-save", "1"], ["run", "scan", "--bogus"],
                 ["run"], ["run", "scan-azimuth", "--duration", "0.1"]):
        with pytest.raises(SystemExit) as info:
            cli.main(argv)
        assert info.value.code == 2, argv
        assert "usage: tolerax" in capsys.readouterr().err  # unknown options: the top-level usage (argparse)
    with pytest.raises(SystemExit) as info:
        cli.main(["run", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "--duration" in out and "Exit codes" in out
    assert cli.main(["run", "--list"]) == 0
    assert "paper-table3-azimuth-a" in capsys.readouterr().out


def test_cli_run_writes_results_and_reports_solver_failure(tmp_path, capsys):
    import xarray as xr

    out = tmp_path / "run"
    argv = ["run", "scan-azimuth", "--duration", "0.05", "--settle", "0", "--n-save", "11", "--out", str(out)]
    assert cli.main(argv) == 0
    capsys.readouterr()
    files = {p.name for p in out.iterdir()}
    assert {"scene.toml", "timeseries.nc", "pointing_error.png", "joint_angle.png", "summary.json", "summary.md"} <= files
    ran = tx.load_scene(out / "scene.toml")
    assert ran == tx.load_scene("scan-azimuth").replace(duration=0.05, settle=0.0, n_save=11)
    # The file's run against the builder call it describes (same compiled program).
    direct = tx.simulate(tx.scan("azimuth", fidelity=("lumped", "ideal")), 0.05, start="steady", n_save=11)
    with xr.open_dataset(out / "timeseries.nc", engine="h5netcdf") as ds:
        assert ds.pointing_error.attrs["units"] == "rad" and ds.time.attrs["units"] == "s"
        assert ds.joint_angle.dims == ("time", "joint") and ds.sizes["time"] == 11
        np.testing.assert_array_equal(ds.pointing_error.values, np.asarray(direct.pointing_error))
        np.testing.assert_array_equal(ds.joint_angle.values, np.asarray(direct.joint_angle))
        assert tx.parse_scene(ds.attrs["scene_toml"]) == ran
    summary = json.loads((out / "summary.json").read_text())
    rms = np.sqrt(np.mean(np.asarray(direct.pointing_error) ** 2)) / tx.ARCSEC
    assert math.isclose(summary["metrics"]["pointing_rms_arcsec"], rms, rel_tol=1e-12)
    assert summary["result"] == "successful" and "--duration 0.05" in summary["command"]
    assert "RMS pointing error" in (out / "summary.md").read_text()
    # The jitter (above 20 Hz, to the saves' Nyquist 100 Hz): the baseline for `design --jitter`.
    from tolerax.mechanism.outputs import pointing_metrics

    jitter = float(pointing_metrics(direct, np.ones(11, dtype=bool), jitter_cutoff=20.0)["pointing_jitter"])
    assert math.isclose(summary["metrics"]["pointing_jitter_arcsec"], jitter, rel_tol=1e-12)
    assert summary["metrics"]["jitter_band_hz"] == [20.0, pytest.approx(100.0)]
    assert "| jitter (RMS of the pointing error over 20-100 Hz) |" in (out / "summary.md").read_text()
    # ... read by a lumped joint, which does not read it as the full stage does: said beside it.
    assert summary["metrics"]["jitter_read_by"] == {"azimuth": "lumped"}
    assert "arcsec (a proxy, not the full stage's: the azimuth joint is lumped, and the jitter is the full stage's vibration" in (
        out / "summary.md").read_text()
    # The output bearing: the ideal pitch joint's output does not translate: no force or runout to
    # read, said so (not "0 N") and null in summary.json; the lumped azimuth joint's own bearing
    # (its output translates in its clearance) is read, and said to be a proxy's.
    table, metrics = (out / "summary.md").read_text(), summary["metrics"]
    assert "| pitch peak output-bearing force | not modelled (the pitch joint is ideal: its output does not translate) |" in table
    assert metrics["pitch_output_force_peak_N"] is None and metrics["pitch_runout_peak_um"] is None
    built = ran.build()
    q = np.asarray(direct.states[0])[:, built.layout.azimuth_q][:, built.azimuth.layout.carrier_xy]
    runout = np.max(np.hypot(q[:, 0], q[:, 1])) * 1e6  # the output's eccentricity in its bearing, from the states
    assert metrics["azimuth_runout_peak_um"] == pytest.approx(runout, rel=1e-6)
    assert f"| azimuth peak runout | {runout:.4g} µm (the azimuth joint is lumped: its own output bearing, not read" in table
    assert metrics["joint_fidelity"] == {"azimuth": "lumped", "pitch": "ideal"}

    # Tolerances no solver can meet: the error control wants a step below dtmin. Only values
    # change, so the compiled program is reused.
    failing = tmp_path / "failing.toml"
    failing.write_text(ran.replace(rtol=1e-14, atol=1e-17, dtmin=1e-4, dt0=2e-4).to_toml())
    assert cli.main(["run", str(failing), "--out", str(tmp_path / "fail")]) == 3
    assert "dt_min_reached" in capsys.readouterr().err
    summary = json.loads((tmp_path / "fail" / "summary.json").read_text())
    assert summary["result"] == "failed" and summary["t_reached_s"] < 0.05
    assert "Failure:" in (tmp_path / "fail" / "summary.md").read_text()


def test_a_shop_cost_table_is_checked_where_it_is_written():
    """`[tolerances.cost]`: a shop's price per grade loads as `tolerax.GradeTable`; a bad one is
    refused naming the file, line and key."""
    from tolerax.io.schema import cost_model

    text = tx.load_scene("scan-azimuth").to_toml() + "\n[tolerances.cost]\ngrades = [6, 7, 8]\ncosts = [2.0, 1.0, 0.8]\n"
    scene_file = tx.parse_scene(text)
    assert isinstance(cost_model(None, scene_file.data["tolerances"]["cost"]), tx.GradeTable)
    bounds = tx.load_scene("scan-azimuth").to_toml().replace("band = 1e-05", "band = 1e-05\nband_range = [2e-06, 1e-06]")
    with pytest.raises(tx.SceneFileError, match="band_range"):
        tx.parse_scene(bounds)
    minima = tx.load_scene("scan-azimuth").to_toml() + '\n[tolerances.min_clearance]\n"azimuth.sun_backlsh" = 5e-06\n'
    with pytest.raises(tx.SceneFileError, match="did you mean 'azimuth.sun_backlash'"):
        tx.parse_scene(minima)
    for bad, match in ((text.replace("[2.0, 1.0, 0.8]", "[2.0, 1.0, 1.2]"), "not increase with the grade"),
                       (text.replace("costs =", "cots ="), "unknown key 'cots'")):
        with pytest.raises(tx.SceneFileError, match=match) as info:
            tx.parse_scene(bad)
        assert "[tolerances.cost]" in str(info.value)


def test_a_tabulated_motion_profile_is_tracked():
    """`profile_times`/`profile_angles`: a step of 1.5 deg over 0.1 s then a hold, as a scene file;
    the commanded angle is SciPy's PCHIP through the points (no overshoot: a step stays a step),
    the rate its derivative, held after the last point; the joint follows it. Bad tables are
    named."""
    import math

    import scipy.interpolate

    times, angles = [0.0, 0.05, 0.15, 0.4], [0.0, 0.0, math.radians(1.5), math.radians(1.5)]
    text = tx.load_scene("scan-azimuth").to_toml().replace(  # the profile replaces the scan's amplitude and period
        "period = 1.0", f"profile_times = {times}\nprofile_angles = {angles}").replace("duration = 0.6", "duration = 0.4")
    text = "\n".join(line for line in text.splitlines() if not line.startswith("amplitude ="))
    text = text.replace('start = "steady"', 'start = "rest"').replace("settle = 0.3", "settle = 0.0")
    scene_file = tx.parse_scene(text)
    servo = scene_file.build().azimuth.drive
    assert isinstance(servo, tx.ProfileServo)
    t = np.linspace(0.0, 0.5, 501)
    reference = scipy.interpolate.PchipInterpolator(times, angles)
    inside = t <= 0.4
    np.testing.assert_allclose(np.asarray(servo.angle(t))[inside], reference(t[inside]), atol=1e-15)
    np.testing.assert_allclose(np.asarray(servo.rate(t))[inside], reference.derivative()(t[inside]), atol=1e-13)
    assert np.all(np.asarray(servo.angle(t))[~inside] == angles[-1]) and np.all(np.asarray(servo.rate(t))[~inside] == 0.0)
    assert np.max(np.asarray(servo.angle(t))) <= angles[-1] * (1 + 1e-12)  # no overshoot
    result = scene_file.simulate()
    joint = np.asarray(result.joint_angle)[:, 0]
    commanded = np.asarray(result.commanded_angle)[:, 0]
    np.testing.assert_allclose(commanded, reference(np.asarray(result.ts)), atol=1e-15)
    # The output takes up the joint's lost motion (100 um clearances and backlash: about 0.012 rad
    # at the output, notebooks/design_and_yield.ipynb) before it moves, overshoots on the
    # reflector's inertia and settles back: at the end within that lost motion of the command.
    assert joint.max() > 0.5 * angles[-1] and abs(joint[-1] - angles[-1]) < 0.013, (joint.max(), joint[-1])
    with pytest.raises(tx.SceneFileError, match="increasing"):
        tx.parse_scene(text.replace(f"profile_times = {times}", "profile_times = [0.0, 0.2, 0.1, 0.4]"))
    with pytest.raises(tx.SceneFileError, match="profile_angles"):
        tx.parse_scene(text.replace(f"profile_angles = {angles}", 'profile_angles = ["a", 0.0, 0.0, 0.0]'))


LIFE_SCENE = """
title = "the planetary scan over a life"
[scene]
kind = "scan"
mode = "azimuth"
fidelity = ["planetary", "ideal"]
[run]
duration = 0.02
start = "rest"
n_save = 41
[life]
years = 4
duty = 0.25
lubricant = "PFPE grease (Braycote-type), vacuum"
estimate = "high"
"""


# `over_life` jitted once for the module (what `tolerax run` and `feature_growth` compute with the
# same lambda): the life tests below trace it once between them, and read the program `tolerax
# run` compiled back from the run's compilation cache.
_over_life = eqx.filter_jit(lambda p, v: p.over_life(v))


def test_life_table_builds_the_mission_life_and_run_reports_it(tmp_path, capsys):
    """`[life]`: the MissionLife it describes (one year of operation: 4 years at a quarter,
    the lubricant's high estimate, 2 points by default), carried into `objective()` (its `_eol`
    outputs); refused keys and values name the line; `tolerax run` writes `life.md` with the
    clearances' growth at each life point (values from `over_life` itself)."""
    from tolerax.design.life import YEAR
    from tolerax.physics.wear import LUBRICANTS

    sf = tx.parse_scene(LIFE_SCENE)
    life = sf.life
    assert float(life.operating_time) == pytest.approx(YEAR, rel=1e-15) and life.points == 2
    assert float(life.wear.rate) == LUBRICANTS["PFPE grease (Braycote-type), vacuum"].high
    assert "pointing_rms_eol" in sf.objective().outputs and tx.load_scene("scan-azimuth").life is None
    assert life.spread is None and life.wear.flanks  # defaults: one wear rate for every unit, the flanks wear
    pfpe = LUBRICANTS["PFPE grease (Braycote-type), vacuum"]
    spread = tx.parse_scene(LIFE_SCENE + "spread = true\nflanks = false\n").life
    assert spread.spread == pytest.approx((pfpe.low / pfpe.high, 1.0), rel=1e-12) and not spread.wear.flanks
    for old, new, message in [
        ("duty = 0.25", "duty = 1.5", "fraction of the life"),
        ("years = 4", "years = -4.0", "non-negative number of years"),
        ("estimate = \"high\"", "estimate = \"worst\"", "estimate='worst' is unknown"),
        ("lubricant = \"PFPE grease (Braycote-type), vacuum\"", "lubricant = \"graphite\"", "unknown lubricant 'graphite'"),
        ("duty = 0.25", "duty = 0.25\nhours = 3.0", "unknown key 'hours'"),
        ("fidelity = [\"planetary\", \"ideal\"]", "fidelity = [\"lumped\", \"ideal\"]", "nothing wears in this scene"),
    ]:
        assert old in LIFE_SCENE
        with pytest.raises(tx.SceneFileError, match=re.escape(message)) as err:
            tx.parse_scene(LIFE_SCENE.replace(old, new))
        assert err.value.table == ("scene" if "lumped" in new else "life") or err.value.table == "life"
    # An end-of-life requirement needs a [life]: refused before any work.
    lifeless = tmp_path / "lifeless.toml"
    lifeless.write_text(LIFE_SCENE.split("[life]")[0])
    with pytest.raises(SystemExit) as info:
        cli.main(["design", str(lifeless), "--requirement", "500", "--require", "pointing_rms_eol=500", "--out", str(tmp_path / "d")])
    assert info.value.code == 2 and "needs a [life] table" in capsys.readouterr().err
    path = tmp_path / "life.toml"
    path.write_text(LIFE_SCENE.replace("start = \"rest\"", "start = \"rest\"\nsettle = 0.0"))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    text = (tmp_path / "out" / "life.md").read_text()
    assert "## Over the mission's life" in text and text in printed
    rows = [line for line in text.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 3 and rows[0].split(" | ")[1] == "0" and rows[2].split(" | ")[1] == "4"
    outputs, depths = _over_life(tx.load_scene(path).objective(), tx.design_of(sf.build()))
    last = rows[2].strip("| ").split(" | ")
    assert float(last[2]) == pytest.approx(float(outputs["pointing_rms"][2]), abs=0.051)
    np.testing.assert_allclose([float(v) for v in last[4:]], np.asarray(depths["azimuth"][2]) * 1e6, rtol=5e-3, atol=1e-12)


def test_design_for_a_life_on_the_command_line(tmp_path, capsys, monkeypatch):
    """`tolerax design SCENE --life YEARS [--wear-spread]`: the scene's `[life]` lasting YEARS
    (its other keys kept, or the defaults without one), the RMS requirement met at the end of
    life too (one budget), each unit's rate drawn over the lubricant's band with `--wear-spread`;
    what reaches the public `propose_design` is read off (the design itself is replaced by a
    recorder that then refuses, so the command stops there with its refusal's exit code 2: the
    design's solves are tested in test_life.py and test_reliability.py). Refused where nothing
    wears, and `--wear-spread` without `--life`."""
    from tolerax.design import propose as _p
    from tolerax.design.life import YEAR, WEAR_FACTOR
    from tolerax.physics.wear import LUBRICANTS

    seen = {}

    def propose(problem, solver=None, **options):  # what reaches it: the ToleranceProblem's objective and requirements
        seen.update(pointing=problem.objective, requirements=problem.requirements)
        raise ValueError("recorded by the test")

    monkeypatch.setattr(_p, "propose_design", propose)
    lifeless = tmp_path / "lifeless.toml"
    lifeless.write_text(LIFE_SCENE.split("[life]")[0])
    args = ["design", str(lifeless), "--requirement", "500", "--yield", "0.9", "--out", str(tmp_path / "d")]
    assert cli.main(args + ["--life", "10", "--wear-spread"]) == 2 and "recorded by the test" in capsys.readouterr().err
    life = seen["pointing"].life
    mos2 = LUBRICANTS["MoS2 sputtered film, vacuum"]
    assert float(life.operating_time) == pytest.approx(10 * YEAR, rel=1e-15) and float(life.wear.rate) == mos2.median
    assert life.spread == pytest.approx((mos2.low / mos2.median, mos2.high / mos2.median), rel=1e-12)
    assert seen["pointing"].uncertain_inputs == (WEAR_FACTOR,)
    assert [(r.output, r.limit) for r in seen["requirements"]] == [("pointing_rms", 500.0), ("pointing_rms_eol", 500.0)]
    # The scene's own [life] keeps its lubricant and duty; --require sets the end of life's own limit.
    own = tmp_path / "own.toml"
    own.write_text(LIFE_SCENE)
    assert cli.main(["design", str(own), "--requirement", "500", "--life", "2", "--require", "pointing_rms_eol=800",
                     "--out", str(tmp_path / "e")]) == 2
    life = seen["pointing"].life
    assert float(life.operating_time) == pytest.approx(0.5 * YEAR, rel=1e-15) and life.spread is None
    assert float(life.wear.rate) == LUBRICANTS["PFPE grease (Braycote-type), vacuum"].high
    assert [(r.output, r.limit) for r in seen["requirements"]] == [("pointing_rms", 500.0), ("pointing_rms_eol", 800.0)]
    capsys.readouterr()
    lumped = tmp_path / "lumped.toml"
    lumped.write_text(LIFE_SCENE.split("[life]")[0].replace('["planetary", "ideal"]', '["lumped", "ideal"]'))
    assert cli.main(["design", str(lumped), "--requirement", "500", "--life", "10", "--out", str(tmp_path / "f")]) == 2
    assert "nothing wears in this scene" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        cli.main(args + ["--wear-spread"])
    assert info.value.code == 2 and "--wear-spread needs --life" in capsys.readouterr().err


def test_the_requirements_are_data_in_the_scene_file(tmp_path, capsys, monkeypatch):
    """`[tolerances]` `yield`, `jitter` (with `jitter_cutoff`) and `require` (further
    requirements by output): what `tolerax design` designs for without the flags, each flag
    overriding its key (`--require` the limit of its own output only); refused values name the
    key; a proposal carries the requirements it met (`with_proposal`), which `tolerax montecarlo`
    then checks by default (the jitter at its cutoff). What reaches `propose_design` is read off
    (a recorder that then refuses: exit 2), as in test_design_for_a_life_on_the_command_line."""
    import types

    from tolerax.cli import commands
    from tolerax.design import propose as _p
    from tolerax.design.requirements import Requirement

    seen = {}

    def propose(problem, solver=None, **options):
        seen.update(statistic=problem.statistic, requirements=problem.requirements, cutoff=problem.objective.jitter_cutoff,
                    problem=problem, check=options["check"])
        raise ValueError("recorded by the test")

    monkeypatch.setattr(_p, "propose_design", propose)
    base = LIFE_SCENE.split("[life]")[0]  # the full planetary stage: it reads the jitter
    text = base + "[tolerances]\nrequirement = 900.0\nyield = 0.95\njitter = 0.3\njitter_cutoff = 30.0\nrequire = {pointing_peak = 2500.0}\n"
    path = tmp_path / "drive.toml"
    path.write_text(text)
    assert cli.main(["design", str(path), "--out", str(tmp_path / "a")]) == 2 and "recorded by the test" in capsys.readouterr().err
    assert float(seen["statistic"].level) == 0.95 and seen["cutoff"] == 30.0
    assert sorted((r.output, r.limit) for r in seen["requirements"]) == [("pointing_jitter", 0.3), ("pointing_peak", 2500.0),
                                                                         ("pointing_rms", 900.0)]
    # In Python the file states the same problem in one call (`SceneFile.problem()`): the same
    # requirements, statistic, zones, cost and objective as the command line's with no option,
    # here with every [tolerances] key a design reads.
    every = text + ('model = "surface"\nfixed = ["azimuth.carrier_clearance"]\nband_range = [2e-6, 40e-6]\n'
                    'min_clearance = {"azimuth.sun_clearance" = 8e-6}\ncost = {grades = [6, 7, 8], costs = [2.0, 1.0, 0.8]}\n')
    path.write_text(every)
    assert cli.main(["design", str(path), "--out", str(tmp_path / "e")]) == 2
    mine, theirs = tx.parse_scene(every).problem(), seen["problem"]
    assert mine.requirements == tuple(theirs.requirements) and mine.statistic == theirs.statistic and mine.cost == theirs.cost
    assert all(isinstance(r.model, tx.Surface) for r in mine.requirements) and isinstance(mine.cost, tx.GradeTable)
    for key, value in mine.zones.options().items():
        if key == "start":
            assert value.names == theirs.zones.start.names and np.array_equal(value.nominal, theirs.zones.start.nominal)
            assert np.array_equal(value.band, theirs.zones.start.band)
        else:
            assert value == theirs.zones.options()[key], key
    names = tx.design_names(mine.objective.scene)
    assert mine.zones.min_clearance == [8e-6 if n == "azimuth.sun_clearance" else 5e-6 for n in names]
    assert mine.zones.fixed == ("azimuth.carrier_clearance",) and mine.zones.band_range == (2e-6, 40e-6)
    assert mine.objective.jitter_cutoff == theirs.objective.jitter_cutoff == 30.0 and mine.objective.life is None
    assert (mine.objective.duration, mine.objective.integrator) == (theirs.objective.duration, theirs.objective.integrator)
    with pytest.raises(tx.SceneFileError, match="sets no RMS pointing requirement"):
        tx.parse_scene(base).problem()
    with pytest.raises(tx.SceneFileError, match=re.escape("needs a [life] table")):
        tx.parse_scene(base + "[tolerances]\nrequirement = 900.0\nrequire = {pointing_rms_eol = 900.0}\n").problem()
    assert tx.parse_scene(LIFE_SCENE + "[tolerances]\nrequirement = 900.0\nrequire = {pointing_rms_eol = 900.0}\n"
                          ).problem().objective.life is not None  # an end-of-life requirement carries the [life]
    path.write_text(text)
    argv = ["design", str(path), "--yield", "0.9", "--jitter", "0.5", "--jitter-cutoff", "25", "--require", "pointing_peak=3000",
            "--require", "tracking_speed_rms=50", "--backend", "processes", "--out", str(tmp_path / "b")]
    assert cli.main(argv) == 2
    assert float(seen["statistic"].level) == 0.9 and seen["cutoff"] == 25.0
    assert seen["check"].backend == "processes" and seen["check"].units == 200  # --backend: how the check's units run
    assert sorted((r.output, r.limit) for r in seen["requirements"]) == [("pointing_jitter", 0.5), ("pointing_peak", 3000.0),
                                                                         ("pointing_rms", 900.0), ("tracking_speed_rms", 50.0)]
    capsys.readouterr()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("pointing_peak = 2500.0", "pointing_bogus = 1.0"))
    with pytest.raises(SystemExit) as info:
        cli.main(["design", str(bad), "--out", str(tmp_path / "c")])
    assert info.value.code == 2 and "pointing_bogus" in capsys.readouterr().err
    for old, new, key, message in [
        ("yield = 0.95", "yield = 1.5", "yield", "fraction in (0, 1)"),
        ("yield = 0.95\n", "", "jitter", "needs a yield"),
        ("jitter_cutoff = 30.0", "jitter_cutoff = -1.0", "jitter_cutoff", "positive number (Hz)"),
        ("pointing_peak = 2500.0", "pointing_jitter = 1.0", "pointing_jitter", "has its own key"),
        ("pointing_peak = 2500.0", "pointing_peak = -1.0", "pointing_peak", "limit must be finite and > 0"),
    ]:
        with pytest.raises(tx.SceneFileError, match=re.escape(message)) as err:
            tx.parse_scene(text.replace(old, new))
        assert err.value.key == key
    # A proposal carries what it met, in place of the scene's own keys.
    sf = tx.parse_scene(text)
    names = tx.design_names(sf.build())
    zones = tx.Tolerances(names, np.full(len(names), 20e-6), np.full(len(names), 5e-6))
    report = types.SimpleNamespace(tolerances=zones, yield_=0.99, drawable=None, cost=1.0, baseline=(0, 0, 2.0),
                                   status="converged", accepted=True, cost_unit="relative, 1 per feature at IT7",
                                   outcomes=[types.SimpleNamespace(requirement=r) for r in (
                                       Requirement("pointing_rms", 800.0), Requirement("pointing_jitter", 0.2),
                                       Requirement("tracking_speed_rms", 40.0))])
    written = tx.parse_scene(tx.save_scene(sf.with_proposal(report, 22.0), tmp_path / "proposal.toml").read_text())
    tol = written.data["tolerances"]
    assert (tol["requirement"], tol["yield"], tol["jitter"], tol["jitter_cutoff"]) == (800.0, 0.99, 0.2, 22.0)
    assert tol["require"] == {"tracking_speed_rms": 40.0}  # the scene's pointing_peak was not designed for: gone
    mc = {}
    monkeypatch.setattr(commands, "run_monte_carlo", lambda parser, scene_file, out, **kw: mc.update(kw))
    assert cli.main(["montecarlo", str(tmp_path / "proposal.toml"), "--n", "4", "--out", str(tmp_path / "mc")]) == 2
    assert (mc["requirement"], mc["jitter_requirement"], mc["jitter_cutoff"]) == (800.0, 0.2, 22.0)


def test_life_comparison_shows_the_wear_allowance(tmp_path):
    """`tolerax.design.life.life_comparison` (what `tolerax design --life` adds to design.md):
    per feature both designs' zones and the growth by wear at the first's middles, equal to
    `over_life`'s end point (the pins: least and most over the planets); both designs simulated
    on the same units at both ends of life, the yields those units give."""
    import types

    from tolerax.design.life import feature_growth, life_comparison

    sf = tx.parse_scene(LIFE_SCENE.replace("start = \"rest\"", "start = \"rest\"\nsettle = 0.0"))
    pointing = sf.objective()
    names = tx.design_names(pointing.scene)
    middle, half = np.full(len(names), 20e-6), np.full(len(names), 10e-6)  # the pins touch within the 0.02 s

    def report(m, b, cost):
        return types.SimpleNamespace(nominal=m, band=b, cost=cost, tolerances=tx.Tolerances(names, m, b))

    growth = feature_growth(pointing, middle)
    _, depths = _over_life(pointing, jnp.asarray(middle))
    end = np.asarray(depths["azimuth"][-1])
    assert growth["azimuth.planet_clearance"] == pytest.approx((end[2:5].min(), end[2:5].max()), rel=1e-12)
    assert growth["azimuth.sun_backlash"] == pytest.approx((end[5:8].min(), end[5:8].max()), rel=1e-12)
    assert growth["azimuth.carrier_clearance"] == pytest.approx((end[1], end[1]), rel=1e-12)
    limits = {"pointing_rms": 400.0, "pointing_rms_eol": 400.0}
    text, results = life_comparison(pointing, report(middle, half, 2.0), report(middle + 20e-6, half, 1.5), limits, 3,
                                    jax.random.key(0), chunk=3)
    rows = [line for line in text.splitlines() if line.startswith("| azimuth.")]
    assert len(rows) == len(names) and rows[2].split(" | ")[1:3] == ["10.0-30.0", "30.0-50.0"]
    g = growth["azimuth.planet_clearance"]
    assert g[1] > 1.001 * g[0] > 0 and rows[2].rstrip(" |").endswith(f"{g[0] * 1e6:.3g}-{g[1] * 1e6:.3g}")
    both, alone = results.values()
    for mc, cost in ((both, "2.000"), (alone, "1.500")):
        rms = mc.dataset["pointing_rms_eol"].values
        met = np.mean(rms <= 400.0)
        assert f"(cost {cost}): pointing_rms " in text and f"pointing_rms_eol {met:.3f}" in text
    assert np.all(both.dataset["pointing_rms"].values < alone.dataset["pointing_rms"].values)  # the same draws, tighter zones


def test_an_unlikely_amplitude_is_noted_with_its_line_not_refused():
    """A scan amplitude of 1.0 (rad: 57 deg; meant as 1 deg) is valid but unlikely: a
    `SceneFileNote` names the file, line and key and the radians for that many degrees, before
    any work; the scene is built as given. A plausible amplitude says nothing."""
    import warnings

    text = tx.load_scene("scan-azimuth").to_toml()
    lines = text.splitlines()
    (k,) = [i for i, line in enumerate(lines) if line.startswith("amplitude =")]
    lines[k] = "amplitude = 1.0"
    with pytest.warns(tx.SceneFileNote, match=rf"my_scan.toml:{k + 1}: \[scene\] amplitude: 1 rad is 57.3 deg.*for 1 deg write 0.0174533"):
        scene = tx.parse_scene("\n".join(lines), source="my_scan.toml")
    assert float(scene.build().azimuth.drive.amplitude) == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tx.parse_scene(text, source="my_scan.toml")
        # Said once, at the user's line: a scene derived from it (regenerated text, other line
        # numbers: `replace`, `with_tolerances`) does not say it again.
        assert float(scene.replace(duration=0.05, settle=0.0).build().azimuth.drive.amplitude) == 1.0
