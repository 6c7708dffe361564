"""Which fidelity reads which output (`tolerax.design.fidelity`): a jitter requirement on a
proxy joint (lumped, mass-scaled) is refused by `propose_design` and `tolerax design` unless
allowed, the lost-motion outputs are read at any fidelity, and the paired-unit agreement of a
proxy with the full stage is the closed form on constructed samples."""

import numpy as np
import pytest

import tolerax as tx
from tolerax import cli
from tolerax.design.fidelity import check_fidelity, fidelity_agreement, joint_fidelities, proxies, read_at


def test_which_fidelity_reads_which_output():
    scaled = tx.load_scene("scan-azimuth-fast").build()
    assert joint_fidelities(scaled) == {"azimuth": "planetary-scaled", "pitch": "ideal"}
    assert joint_fidelities(tx.scan("dual", fidelity=("lumped", "planetary"))) == {"azimuth": "lumped", "pitch": "planetary"}
    jitter, rms = tx.Requirement("pointing_jitter", 0.2), tx.Requirement("pointing_rms", 700.0)
    assert read_at(jitter) == "planetary" and read_at(rms) == "any"
    assert read_at(tx.Requirement("pointing_rms", 700.0, fidelity="planetary")) == "planetary"
    assert proxies(scaled, "planetary") == {"azimuth": "planetary-scaled"} and proxies(scaled, "any") == {}
    mixed = tx.scan("dual", fidelity=("lumped", "planetary"))
    assert proxies(mixed, "planetary") == {"azimuth": "lumped"} and proxies(mixed, "planetary-scaled") == {"azimuth": "lumped"}
    # The lost-motion requirement is read on the proxy; the jitter is not, and the refusal says
    # which joint, which output and what to do.
    assert check_fidelity(scaled, [rms]) == []
    with pytest.raises(ValueError, match="azimuth joint is planetary-scaled") as refused:
        check_fidelity(scaled, [rms, jitter])
    assert "jitter <= 0.2 arcsec is read at planetary fidelity" in str(refused.value) and "allow_proxy=True" in str(refused.value)
    notes = check_fidelity(scaled, [rms, jitter], allow_proxy=True)
    assert len(notes) == 1 and "planetary-scaled" in notes[0]
    with pytest.raises(ValueError, match="fidelity must be"):
        tx.Requirement("pointing_rms", 700.0, fidelity="full")


def test_propose_design_refuses_the_jitter_on_the_scaled_stage():
    """Before any simulation (no Auto() probe, no compile: seconds): the scaled stage's jitter
    requirement is refused, naming the joint and the remedy; on the full stage the same
    requirement passes the check."""
    sf = tx.load_scene("scan-azimuth-fast")
    pointing = sf.objective(jitter_cutoff=20.0)
    with pytest.raises(ValueError, match="planetary-scaled"):
        tx.propose_design(tx.ToleranceProblem(pointing, [tx.Requirement("pointing_rms", 1000.0), tx.Requirement("pointing_jitter", 0.2)],
                                              tx.Yield(0.9)))
    full = tx.load_scene("scan-azimuth-planetary").build()
    assert check_fidelity(full, [tx.Requirement("pointing_jitter", 0.2)]) == []


def test_tolerax_design_refuses_the_jitter_on_a_proxy(tmp_path, capsys):
    """`tolerax design --jitter` on the mass-scaled scene exits 2 before any work, saying which
    joint does not read the jitter and to give --fidelity planetary or --allow-proxy."""
    out = tmp_path / "no"
    code = cli.main(["design", "scan-azimuth-fast", "--yield", "0.9", "--jitter", "0.2", "--requirement", "1000", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "azimuth joint is planetary-scaled" in err and "--fidelity planetary" in err and "--allow-proxy" in err
    assert not (out / "proposal.toml").exists()


def test_paired_agreement_is_the_closed_form():
    """A proxy reading 0.35 of the full stage's output with independent noise: the ratio of the
    means is 0.35 within its interval, which holds the sample ratio of means by construction and
    narrows as 1/sqrt(n); the correlation is that of the construction."""
    rng = np.random.default_rng(3)
    n = 400
    full = rng.uniform(1.0, 2.0, n)
    proxy = 0.35 * full + rng.normal(0.0, 0.02, n)
    got = fidelity_agreement(full, proxy)
    assert got["n"] == n and got["ratio"] == pytest.approx(np.mean(proxy) / np.mean(full), rel=1e-12)
    lo, hi = got["interval"]
    assert lo < 0.35 < hi and hi - lo < 0.01
    expected_corr = 0.35 * np.std(full) / np.sqrt(0.35**2 * np.var(full) + 0.02**2)
    assert got["correlation"] == pytest.approx(expected_corr, abs=0.02)
    quarter = fidelity_agreement(full[: n // 4], proxy[: n // 4])
    assert (quarter["interval"][1] - quarter["interval"][0]) / (hi - lo) == pytest.approx(2.0, rel=0.3)
    # A unit that failed at either fidelity is left out of both.
    full[0] = np.nan
    assert fidelity_agreement(full, proxy)["n"] == n - 1
