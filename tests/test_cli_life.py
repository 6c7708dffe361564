"""`--life YEARS` on `tolerax montecarlo` and `tolerax run`: the scene's `[life]` set from the
flag by the same helper as `design --life` (`tolerax.cli.common.with_life`), refused before any
simulation where nothing wears. Nothing is simulated here: the commands are replaced by ones that
keep their arguments, and the objective is only built."""

import importlib

import pytest

import tolerax as tx
from tolerax import cli
from tolerax.cli.commands import montecarlo_scene
from tolerax.design.life import YEAR

main_module = importlib.import_module("tolerax.cli.main")  # the module (tolerax.cli.main is also the function)


def _kept(monkeypatch, name):
    """Replace the command `name` (`montecarlo_command`, `run_command`) by one that keeps its
    parser and arguments and returns 0."""
    kept = {}

    def keep(parser, args):
        kept.update(parser=parser, args=args)
        return 0

    monkeypatch.setattr(main_module, name, keep)
    return kept


def test_montecarlo_life_sets_the_objective_s_mission_life(tmp_path, monkeypatch):
    """`--life 10` on a planetary scene without `[life]`: the objective's life is 10 years at
    duty 1 with 2 points (design's defaults); on a scene with a `[life]`, its years replaced and
    its other keys (duty, points) kept."""
    kept = _kept(monkeypatch, "montecarlo_command")
    assert cli.main(["montecarlo", "scan-azimuth-planetary", "--life", "10", "--out", str(tmp_path / "mc")]) == 0
    assert kept["args"].life == 10.0
    life = montecarlo_scene(kept["parser"], kept["args"]).objective().life
    assert float(life.operating_time) == pytest.approx(10 * YEAR, rel=1e-15) and life.points == 2 and life.spread is None
    # The scene's own [life]: 4 years replace its 2, its duty and points kept.
    text = tx.load_scene("scan-azimuth-planetary").to_toml() + "\n[life]\nyears = 2.0\nduty = 0.5\npoints = 3\n"
    path = tmp_path / "own.toml"
    path.write_text(text)
    assert cli.main(["montecarlo", str(path), "--life", "4", "--out", str(tmp_path / "mc")]) == 0
    life = montecarlo_scene(kept["parser"], kept["args"]).objective().life
    assert float(life.operating_time) == pytest.approx(4 * YEAR * 0.5, rel=1e-15) and life.points == 3
    # Without the flag, the scene's [life] as written.
    assert cli.main(["montecarlo", str(path), "--out", str(tmp_path / "mc")]) == 0
    assert kept["args"].life is None
    assert float(montecarlo_scene(kept["parser"], kept["args"]).objective().life.operating_time) == pytest.approx(2 * YEAR * 0.5)


@pytest.mark.parametrize("command", ["montecarlo", "run"])
def test_life_is_refused_where_nothing_wears_before_any_simulation(command, tmp_path, capsys):
    """On the lumped scan (nothing wears) `--life 10` exits 2 before anything is simulated or
    written, saying that the table the flag added has nothing to wear and what to change; a
    life that is not a positive number of years is refused by the parser."""
    out = tmp_path / "out"
    assert cli.main([command, "scan-azimuth", "--life", "10", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"tolerax {command} --life: " in err and "the [life] table that --life 10 added: nothing wears" in err
    assert "planetary fidelity" in err and "[scene] fidelity" in err
    assert not out.exists()
    with pytest.raises(SystemExit) as info:
        cli.main([command, "scan-azimuth-planetary", "--life", "0", "--out", str(out)])
    assert info.value.code == 2 and "--life" in capsys.readouterr().err


def test_run_takes_life(tmp_path, monkeypatch):
    kept = _kept(monkeypatch, "run_command")
    assert cli.main(["run", "scan-azimuth-planetary", "--life", "7.5", "--out", str(tmp_path / "run")]) == 0
    assert kept["args"].life == 7.5
