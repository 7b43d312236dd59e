"""Selection inside the folds and which robot effects are testable (issue 52).

The held-out gain the diagnosis reports is that of its whole procedure -- each outer fold chooses its own
effect, joints and combination from its training rows alone -- and a cause is named only when the folds
agree on it. A compliance is tested only where the joint's logged torque varies well beyond the torque
sensor's noise.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import replace

import numpy as np
import pytest

from lasercal.collector.cli.main import main
from lasercal.solver.analysis.diagnose import TORQUE_NOISE_NM, TORQUE_SPREAD_RATIO, diagnose
from lasercal.solver.analysis.stats import carriers, grouped_folds
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import residuals
from lasercal.solver.kinematics.effects import Extension
from tests.test_diagnose import sim

COMPLIANCE2 = Extension("joint_compliance", (2,), None, np.array([1.2e-4]))


def simulated(tmp_path, sheet, seed: int, measured: str = "1"):
    """`lasercal simulate` of a session on the sheet laid at 452, 3 mm, 1 deg (75 captures at P1-P5; a
    camera session by default, every spot measured at 0.03 mm; ``measured="0"``: aimed by eye at 0.5 mm),
    loaded; as benchmarks/bench_diagnose_nested.py makes them."""
    s = str(tmp_path / f"s{measured}_{seed}")
    argv = ["simulate", "panda_thesis_identified", "--layout", str(sheet), "--sheet-pose", "452", "3", "1.0"]
    argv += ["--per-point", "15", "--aim-noise", "0.5", "--measured", measured, "--seed", str(seed), "-o", s]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0
    return load_session(s)


# seed 61: every fold chooses the compliance at joint 2 alone; seed 63: the whole session and three folds
# add an eccentricity at joint 3 to it (kept by the whole session's cross-validation), two folds do not --
# there the outer folds' gain differs from the whole session's choice refitted in each fold
@pytest.mark.parametrize("seed, same", [(61, 5), (63, 3)])
def test_a_planted_compliance_is_named_by_agreeing_folds_and_its_gain_is_the_outer_folds(
    tmp_path, seed, same
):
    d = diagnose(sim(tmp_path, COMPLIANCE2, seed), n_boot=0, k=5)
    acc = d.acceptance
    lead = d.extension.parts[0]
    assert lead.effect == "joint_compliance" and lead.joints == (2,)
    assert acc["selection"] == "inside each fold" and acc["folds_agreed"]
    assert len(acc["fold_choices"]) == 5 and acc["folds_agree"] == 5 and acc["folds_needed"] == 4
    assert acc["folds_same_cause"] == same
    # recomputed independently: each fold diagnosed on its training rows alone (the F tests deciding, no
    # inner folds), its own finding fitted there and scored on its held-out rows
    s = d.session
    fold = grouped_folds(s, 5, 0)
    counted = (d.geometric.weights > 0) & carriers(s)
    r_geo, r_ext = np.full((s.m, 2), np.nan), np.full((s.m, 2), np.nan)
    labels = []
    for i in range(5):
        test = fold == i
        own = diagnose(s.subset(~test), n_boot=0, k=0)
        labels.append(own.extension.label if own.extension is not None else "none")
        geo, ext = own.geometric, own.extended or own.geometric
        r_geo[test] = residuals(geo.model, None, s.subset(test))
        r_ext[test] = residuals(ext.model, ext.extension, s.subset(test))
    assert labels == [c["label"] for c in acc["fold_choices"]]
    rms = {m: np.sqrt(np.mean(np.sum(r[counted] ** 2, axis=1))) for m, r in (("g", r_geo), ("e", r_ext))}
    np.testing.assert_allclose([d.holdout_rms["geometric"], d.holdout_rms["extended"]], [rms["g"], rms["e"]])
    np.testing.assert_allclose(d.gain_percent, 100 * (rms["g"] - rms["e"]) / rms["g"], rtol=1e-9)
    assert d.statistics["extended"]["holdout"] == d.holdout_rms["extended"]


def test_a_joint_whose_torque_is_the_sensors_noise_gets_no_compliance_test(tmp_path, sheet):
    s = simulated(tmp_path, sheet, 3)
    tau = s.tau.copy()
    # joint 1 vertical: it carries no gravity load, its logged torque is the sensor's noise alone
    tau[:, 0] = np.random.default_rng(0).normal(0.0, TORQUE_NOISE_NM, s.m)
    d = diagnose(replace(s, tau=tau), n_boot=0, k=0)
    assert "noise" in d.untested["joint_compliance at joint 1"]
    assert all(t.label != "joint_compliance[joint 1]" for t in d.tests)
    assert "joint_compliance at joint 1" not in d.unseen
    # joint 2 carries the arm: tested
    assert np.std(tau[:, 1]) > TORQUE_SPREAD_RATIO * TORQUE_NOISE_NM
    assert any(t.label == "joint_compliance[joint 2]" for t in d.tests)


def test_null_eye_sessions_name_less_than_the_whole_session_selection(tmp_path, sheet):
    # benchmarks/bench_diagnose_nested.py 20, world 'none, eye' (seeds 700-719, no effect): the selection on
    # the whole session refitted per fold named 2 of 20 (707: drift at joint 2; 714: encoder eccentricity
    # at joint 5), the selection inside the folds 1 (707: all five folds choose the drift, a pattern they
    # share). These three draws hold both of the old findings; the bound is the measured count of the new
    # procedure on them (fixed seeds: deterministic), one below the old's. Over the 20 draws the new rate
    # is 1/20, its 95 % binomial upper limit 25 %.
    found = {}
    for seed in (700, 707, 714):
        d = diagnose(simulated(tmp_path, sheet, seed, measured="0"), n_boot=0, k=5)
        found[seed] = d
    assert sum(d.effect != "none" for d in found.values()) <= 1
    d = found[714]  # the whole session's choice, refused: the folds chose other causes and lost held out
    assert d.effect == "none" and d.proposed.label == "encoder_eccentricity at joint 5"
    acc = d.acceptance
    assert acc["folds_agree"] < acc["folds_needed"] and not acc["folds_agreed"]
    assert len({c["label"] for c in acc["fold_choices"]}) > 1 and "disagreement" in acc
    assert d.holdout_rms["extended"] == d.holdout_rms["geometric"]
