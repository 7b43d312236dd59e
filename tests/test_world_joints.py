"""The fake world's joints (collector/worlds/truejoints.py, eqs. W4-W6) against the solver's, two codes
written apart: the world draws a session's effects with its own frames (closed-form exponentials, checked
against scipy's ``expm``), its own Jacobian-transpose gravity sum and its own fixed point; the solver fits
with ``poe_chain``, ``gravity_torques``, ``Extension``/``JointMap`` and ``deflected``. Where both read the
same truth file they must agree to round-off, so an error in either shows here, and the diagnosis tests that
run on the world's sessions test the solver on data its own forms did not draw."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lasercal.collector.worlds.fakeeffects import arm_effects
from lasercal.collector.worlds.truearm import link_frames, link_frames_many
from lasercal.solver.formats.robots import load_model
from lasercal.solver.kinematics.effects import extension_from_model
from lasercal.solver.kinematics.elastic import deflected
from lasercal.solver.kinematics.gravity import gravity_torques, with_payload
from lasercal.solver.kinematics.joint_map import joint_map_from_model

PANDA = load_model("panda_thesis_identified")
EXTENSIONS = {
    "joint_compliance": {"units": "rad/Nm", "joints": [2, 4], "c": [1.2e-4, -0.8e-4]},
    "encoder_eccentricity": {"units": "rad", "joints": [3], "a": [2e-4], "b": [-1e-4]},
    "drift": {"units": "rad/s", "joints": [1], "r": [3e-7], "t0_s": 5.0},
    "joint_map": {
        "units": "rad",
        "joints": [6],
        "step": 0.5,
        "start": [-0.5],
        "values": [[1e-4, -2e-4, 3e-4, 0.0]],
    },
}
PAYLOAD = {"mass": 0.7, "com": [0.0, 0.0, 80.0]}


def configs(m: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(PANDA.limits, float).T
    return rng.uniform(lo, hi, (m, PANDA.n))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_the_world_frames_are_scipys_matrix_exponentials(seed):
    """eq. 3.51 in closed form, vectorised, against scipy's expm one configuration at a time."""
    q = configs(4, seed)
    many = link_frames_many(np.asarray(PANDA.screws), q)
    one = np.array([link_frames(PANDA, qi) for qi in q])
    assert np.abs(many - one).max() < 1e-9  # mm on a 1 m arm: round-off, 1e-12 relative


def world_and_solver(extensions: dict, payload=None):
    truth = PANDA.replace(
        extensions=extensions, identification={"payload": payload} if payload else PANDA.identification
    )
    effects = arm_effects(truth)
    solver_model = with_payload(truth, payload and (payload["mass"], np.array(payload["com"])))
    parts = (extension_from_model(extensions, "t", truth.n), joint_map_from_model(extensions))
    return effects, solver_model, SolverSum(tuple(p for p in parts if p is not None))


class SolverSum:
    """The solver's joint effects (a Combination and a JointMap) summed, as ``deflected`` takes them."""

    def __init__(self, parts):
        self.parts = parts

    def true_q(self, q, t=None, tau=None):
        return q + sum(p.true_q(q, t, tau) - q for p in self.parts)


def test_the_world_gravity_is_the_solvers_gravity():
    """eq. W4 (per-pair cross products) and the solver's space-Jacobian einsum, with a flange load."""
    effects, model, _ = world_and_solver(EXTENSIONS, PAYLOAD)
    q = configs(200, 1)
    world, solver = effects.torques(q), gravity_torques(model, q)
    assert np.abs(solver).max() > 10  # a real load: the Panda's joints 2 and 4 carry tens of Nm
    assert np.abs(world - solver).max() < 1e-10


def test_the_world_links_are_the_solvers_deflected_links():
    """eq. W6's fixed point under every effect at once against ``deflected``; the world's encoders
    invert it."""
    effects, model, ext = world_and_solver(EXTENSIONS, PAYLOAD)
    q = configs(100, 2)
    t = 40.0
    world = effects.links(q, t)
    solver, _ = deflected(model, ext, q, np.full(len(q), t))
    assert np.abs(world - q).max() > 1e-3  # the effects move the links by milliradians
    assert np.abs(world - solver).max() < 1e-12
    assert np.abs(effects.encoders(world, t) - q).max() < 1e-12


def test_a_wrong_sign_in_the_world_shows():
    """The comparison is sharp: the world's compliance with its sign flipped is millions of times off."""
    flipped = {**EXTENSIONS, "joint_compliance": {**EXTENSIONS["joint_compliance"], "c": [-1.2e-4, 0.8e-4]}}
    effects, _, _ = world_and_solver(flipped, PAYLOAD)
    _, model, ext = world_and_solver(EXTENSIONS, PAYLOAD)
    q = configs(20, 3)
    assert np.abs(effects.links(q, 40.0) - deflected(model, ext, q, np.full(20, 40.0))[0]).max() > 1e-4


def test_simulate_draws_the_arm_in_the_world_and_agrees_with_the_solvers_forms(tmp_path, monkeypatch):
    """``lasercal simulate`` hides a compliance through the world's joints (eqs. W4-W6); the session it
    writes equals, to round-off, one drawn by the solver's own forms (``simulate_captures`` without an arm):
    the data a diagnosis test reads is not the solver's, and yet means the same truth."""
    import lasercal.collector.hardware as factory
    from lasercal.simulation import simulate
    from lasercal.solver.formats.session import load_session

    kw = dict(
        layout="thesis", per_point=5, seed=3, robot="panda", effect="joint_compliance", effect_size=1.2e-4
    )
    calls = []
    world_joints = factory.world_joints
    monkeypatch.setattr(factory, "world_joints", lambda truth: calls.append(truth) or world_joints(truth))
    simulate("panda_thesis_identified", tmp_path / "world", **kw)
    assert len(calls) == 1 and calls[0].extensions["joint_compliance"]["c"] == [1.2e-4]
    monkeypatch.setattr(factory, "world_joints", lambda truth: None)
    simulate("panda_thesis_identified", tmp_path / "solver", **kw)
    a, b = (
        load_session(tmp_path / "world"),
        load_session(tmp_path / "solver"),
    )
    assert np.abs(a.q - b.q).max() < 1e-12 and np.abs(a.tau - b.tau).max() < 1e-10
