"""Synthetic experiments: sessions whose truth is a known robot, and simulated validation runs.

Aiming noise follows the thesis (Section 4.2): Gaussian noise is added to the reference
point before the true robot's configuration is computed, so the operator's beam hits a
point near, not at, the reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.errors import AimingError
from lasercal.solver.formats.session import Layout
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim, polish
from lasercal.solver.kinematics.effects import Combination, Extension
from lasercal.solver.kinematics.gravity import gravity_torques
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.streams import Seed, child, root, stream


@dataclass(frozen=True)
class SimulatedCaptures:
    """Captures of a simulated session (the columns of captures.csv).

    Attributes
    ----------
    point : (m,) array of str
    t : (m,) array, s
    q : (m, n) array, rad
    hit : (m, 3) array, where the true beam really met the plane, mm
    tau : (m, n) array or None, logged joint torques (gravity model plus sensor noise), Nm
    """

    point: np.ndarray
    t: np.ndarray
    q: np.ndarray
    hit: np.ndarray
    tau: np.ndarray | None = None


def simulate_captures(
    truth: RobotModel,
    layout: Layout,
    per_point: int,
    aim_noise: float,
    rng: Seed,
    points=None,
    effect: Extension | Combination | None = None,
    tau_noise: float = 0.05,
    aims: dict | None = None,
    arm=None,
) -> SimulatedCaptures:
    """Configurations of the true robot aimed at each reference point with aiming noise.

    Parameters
    ----------
    truth : RobotModel, the robot's true geometry
    layout : Layout
    per_point : int, captures per point
    aim_noise : float, std of the in-plane aiming error per axis, mm
    rng : int, SeedSequence or Generator, the root of the session's streams (:mod:`solver.streams`): each
        point's poses and aiming noise, the capture times and the torque noise draw from streams of their
        own, so a decision flipped by round-off at one point changes nothing elsewhere
    points : list of point names (default: the layout's calibration points)
    effect : Extension, a hidden non-geometric effect with its true parameters: the logged
        angles are the true ones minus the effect's correction (solved by fixed-point
        iteration), or the operator aims at the point's true position (point offset)
    tau_noise : float, std of the logged joint torques about the gravity model, Nm
    aims : dict point name -> (per_point, 2) array, optional: where in the plane each capture aims, mm off
        its point (a camera session's coach aims anywhere on the sheet); default at the point
    arm : object or None, the true arm's joints drawn by code other than the solver's (``lasercal
        simulate``: the simulated world's, eqs. W4-W6): ``torques(q_link (m, n)) -> (m, n)`` Nm and
        ``encoders(q_link, t (m,)) -> (m, n)`` rad; it replaces ``effect``'s joint part and the gravity model
        (None: the solver's own, :func:`gravity_torques` and ``effect.logged_q``)

    Returns
    -------
    SimulatedCaptures, in the order an operator takes them (point by point), t ~ 20 s apart
    """
    names = list(points or layout.calibration)
    seed = root(rng)
    qs, hits = [], []
    for name in names:
        p = layout.points[name]
        q = layout.aim_at(truth, name, per_point, child(seed, "poses", name))
        noise = stream(seed, "aiming", name).normal(0, aim_noise, (per_point, 2))
        hit = p + np.c_[noise, np.zeros(per_point)]
        if aims is not None:
            hit[:, :2] += aims[name]
        if effect is not None and effect.point == name:
            hit[:, :2] += effect.params[:2]
        qs.append(polish(truth, q, hit) if aim_noise > 0 else q)
        hits.append(hit)
    q = np.concatenate(qs)
    if not truth.within_limits(q).all():  # polishing moved a pose by far less than aim()'s limit margin
        raise AimingError("a noisy aim left the joint limits; lower the aiming noise")
    t = np.cumsum(stream(seed, "times").uniform(10.0, 30.0, len(q)))
    if arm is not None:
        tau_true = arm.torques(q) if truth.links else None
        q = arm.encoders(q, t)
    else:
        tau_true = gravity_torques(truth, q) if truth.links else None
        if effect is not None and effect.acts_on_joints:
            q = effect.logged_q(q, t, tau_true)
    tau = None
    if tau_true is not None:  # the logged torques: the true ones plus sensor noise
        tau = tau_true + stream(seed, "torques").normal(0, tau_noise, tau_true.shape)
    return SimulatedCaptures(
        np.repeat(np.array(names, dtype=object), per_point), t, q, np.concatenate(hits), tau
    )


def validation_spots(truth: RobotModel, model: RobotModel, point, n: int, rng: Seed, **aim_kw) -> np.ndarray:
    """The thesis's validation (Section 4.3): ``model`` computes n configurations aiming at the
    point; the true robot's beam lands at the returned spots (n, 3), mm."""
    point = np.asarray(point, dtype=float)
    q = aim(model, point, n, rng, **aim_kw)
    return predict_spots(truth, q, point[2])[0]


def random_configs(model: RobotModel, m: int, rng: np.random.Generator, margin: float = 0.05) -> np.ndarray:
    """m configurations (m, n) drawn uniformly inside the joint limits (less ``margin``, rad or mm)."""
    lo, hi = model.limits[:, 0] + margin, model.limits[:, 1] - margin
    return rng.uniform(lo, hi, (m, model.n))


def simulate_positions(
    truth: RobotModel,
    q: np.ndarray,
    names: np.ndarray,
    noise_mm: float,
    rng: np.random.Generator,
    effect: Extension | Combination | None = None,
    tau: np.ndarray | None = None,
) -> np.ndarray:
    """Sensor readings (m, 3) mm of the truth's targets (its ``targets`` and ``sensor_pose``) at the logged
    configurations q, with N(0, noise_mm^2) per axis; a hidden joint ``effect`` acts on q (with ``tau``)."""
    from lasercal.solver.identify.position import sensor_points

    q_true = effect.true_q(q, np.zeros(len(q)), tau) if effect is not None else q
    return sensor_points(truth, q_true, names) + rng.normal(0.0, noise_mm, (len(q), 3))
