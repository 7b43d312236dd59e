"""Elasticity under own weight on a simulated tree robot: known joint and lateral compliances recovered."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

from lasercal.collector.report.text import format_diagnosis
from lasercal.solver.analysis import diagnose as diag
from lasercal.solver.analysis.diagnose import diagnose, session_torques
from lasercal.solver.analysis.stats import solve_report
from lasercal.solver.formats.justin import craig_row
from lasercal.solver.formats.positions import position_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.position import sensor_points
from lasercal.solver.kinematics.effects import Extension, combine
from lasercal.solver.kinematics.elastic import bending, deflected
from lasercal.solver.kinematics.model import Link, RobotModel
from lasercal.solver.kinematics.tree import with_lateral_axes

ALPHA = 1e-3  # family-wise false-selection rate of these tests' diagnoses: a spurious term 1 seed in 1000


def tree_robot() -> RobotModel:
    """A torso joint carrying two 3-joint arms (Craig DH rows, mm), 2-4 kg per link, two hand targets."""
    rows = {  # (d, theta deg, r, alpha deg)
        "right": [(0, 0, 0, 90), (0, 0, 400, 0), (0, -90, 350, -90)],
        "left": [(0, 0, 0, -90), (0, 0, 400, 0), (0, 90, 350, 90)],
    }
    torso = craig_row(500.0, 0.0, 0.0, 0.0)
    frames, names, parents = [torso], ["torso_1"], [-1]
    for side, sign in (("right", -1), ("left", 1)):
        T = torso @ np.array([[1, 0, 0, 0], [0, 1, 0, sign * 200.0], [0, 0, 1, 300.0], [0, 0, 0, 1]])
        for k, (d, th, r, al) in enumerate(rows[side]):
            T = T @ craig_row(d, np.radians(th), r, np.radians(al))
            parents.append(0 if k == 0 else len(frames) - 1)
            frames.append(T)
            names.append(f"{side}_{k + 1}")
    frames = np.array(frames)
    screws = np.array([np.r_[F[:3, 2], -np.cross(F[:3, 2], F[:3, 3])] for F in frames])
    links = tuple(Link(2.0 + k % 3, F[:3, 3] + F[:3, 0] * 150.0) for k, F in enumerate(frames))
    tips = {arm: frames[j][:3, 3] + frames[j][:3, 0] * 100 for arm, j in (("right", 3), ("left", 6))}
    n = len(names)
    model = RobotModel(
        name="tree",
        joint_names=tuple(names),
        screws=screws,
        limits=np.tile([-2.5, 2.5], (n, 1)),
        laser_dir=np.array([0, 0, 1.0]),
        aperture=tips["right"],
        targets=tips,
        links=links,
        parents=tuple(parents),
        joint_links=tuple(names[:3] + ["right_hand"] + names[4:6] + ["left_hand"]),
        lateral_of=(-1,) * n,
        target_links={"right": "right_hand", "left": "left_hand"},
    )
    return with_lateral_axes(model, frames)


def simulate(model, truth_ext, m: int, noise: float, seed: int):
    """A position session of both hands at m random poses, the deflected truth seen by a sensor."""
    rng = np.random.default_rng(seed)
    qc = rng.uniform(-2.0, 2.0, (m, int(model.real.sum())))
    q = np.repeat(model.described(qc), 2, axis=0)
    names = np.tile(np.array(["right", "left"], dtype=object), m)
    X = np.eye(4)
    X[:3, 3] = [2000.0, -500.0, 300.0]
    truth = model.replace(sensor_pose=X)
    qt, _ = deflected(truth, truth_ext, q)
    y = sensor_points(truth, qt, names) + rng.normal(0, noise, (len(q), 3))
    return position_session(model.replace(targets={}), q, y, names)


def _truth(model):
    """Joint compliance on right_2 and left_1 about their axes, lateral compliance of right_1 about x."""
    idx = {nm: j + 1 for j, nm in enumerate(model.joint_names)}
    jc = Extension("joint_compliance", (idx["right_2"], idx["left_1"]), None, np.array([-4e-4, -3e-4]))
    lc = Extension("lateral_compliance", (idx["right_1.x"],), None, np.array([-5e-4]))
    return combine([jc, lc])


def test_deflected_pose_is_a_fixed_point_of_the_gravity_torques():
    model = tree_robot()
    ext = _truth(model)
    q = model.described(np.random.default_rng(1).uniform(-2, 2, (5, 7)))
    qt, tau = deflected(model, ext, q)
    from lasercal.solver.kinematics.gravity import gravity_torques

    assert np.abs(ext.true_q(q, None, gravity_torques(model, qt)) - qt).max() < 1e-12
    assert np.abs(qt - q).max() > 1e-3  # the bend is real: milliradians


@pytest.mark.parametrize("linear", [False, True], ids=["refit-per-term", "linearised"])
def test_extend_auto_recovers_known_joint_and_lateral_compliances(linear, monkeypatch):
    if linear:  # the selection a humanoid's many candidates use
        monkeypatch.setattr(diag, "LINEAR_SELECTION", 0)
    model = tree_robot()
    truth = _truth(model)
    s = simulate(model, truth, 80, 0.02, seed=5)
    d = diagnose(s, alpha=ALPHA, n_boot=0, k=0)
    assert d.extension is not None
    found = {(e.effect, j): c for e in d.extension.parts for j, c in zip(e.joints, e.params)}
    se = {(e.effect, j): s_ for e in d.extension.parts for j, s_ in zip(e.joints, e.std_errors)}
    want = {(e.effect, j): c for e in truth.parts for j, c in zip(e.joints, e.params)}
    assert set(found) == set(want)  # them and nothing else
    for k, c in want.items():  # within 4 standard errors (+ the fixed point's < 1e-3 relative torque change)
        assert abs(found[k] - c) < 4 * se[k] + 1e-3 * abs(c), (k, found[k], c, se[k])
    words = [b["words"] for b in bending(model, d.extension, d.session.tau)]
    assert any("joint right_1 (joint 1 of the right arm) bends about its x axis" in w for w in words)
    # every line a person reads names the tree's joints by name, never by their index among the 16
    text = format_diagnosis(d)
    finding = next(line for line in text.splitlines() if line.startswith("finding:"))
    assert "at joint right_1.x, right_2, left_1 " in finding, finding
    assert "  c[right_2] = " in text and "  c[right_1.x] = " in text
    assert not re.search(r"joint \d|\b[abc]\d+ =", text), text


def test_geometry_only_data_select_no_elasticity():
    model = tree_robot()
    s = simulate(model, combine([Extension("joint_compliance", (2,), None, np.zeros(1))]), 80, 0.02, seed=6)
    d = diagnose(s, alpha=ALPHA, n_boot=0, k=0)
    assert d.effect == "none"


def test_solve_report_per_target_rms_is_the_extended_models():
    """The solve table's per-target RMS after an elastic fit: the extended model's, the extension applied once
    to the logged joints (an independent evaluation of its predictions), at the noise, not the bend."""
    model = tree_robot()
    truth = _truth(model)
    s = simulate(model, truth, 40, 0.02, seed=7)
    s = replace(s, tau=session_torques(s)[0])
    ident = fit(s, truth)
    rep = solve_report(s, ident)
    used = ident.weights > 0
    q = ident.extension.true_q(s.q, s.t, s.tau)
    geo = fit(s)
    for nm in ("right", "left"):
        sel = (s.point == nm) & used
        r = np.linalg.norm(sensor_points(ident.model, q[sel], s.point[sel]) - s.target[sel], axis=1)
        after = rep["targets"][nm]["after_rms_mm"]
        assert after == pytest.approx(np.sqrt(np.mean(r**2)), abs=1e-5)
        assert after < 2 * 0.02 * np.sqrt(3)  # the noise (0.035 mm), not the bend
        assert after < 0.2 * solve_report(s, geo)["targets"][nm]["after_rms_mm"]
