"""Elasticity under the robot's own weight: the deflected pose, and which joints bend, in words.

A compliance c_j (rad/Nm) on joint j, about its axis (``joint_compliance``) or about an axis across
it (``lateral_compliance`` on a lateral axis, :mod:`solver.kinematics.tree`), bends the joint by
c_j tau_j, tau the gravity torques (:mod:`solver.kinematics.gravity`). The deflection moves the masses,
so the torques are those of the deflected pose: q_true is the fixed point (eq. E1)

    q_true = q + dq(tau(q_true)),   iterated from tau(q);

a deflection of milliradians changes the lever arms by as little, so each iteration shrinks the change
a thousandfold and a few reach round-off (:func:`deflected`).
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.kinematics.gravity import gravity_torques
from lasercal.solver.kinematics.joint_names import joint_label
from lasercal.solver.kinematics.model import RobotModel

FIXED_POINT_ITERATIONS = 10  # at most; each shrinks the change by the bend (mrad): 3-4 reach round-off
FIXED_POINT_TOL = 1e-13  # rad: the iteration stops when no joint moves more


def deflected(model: RobotModel, ext, q: np.ndarray, t=None, iterations: int = FIXED_POINT_ITERATIONS):
    """The deflected joint values and the torques that hold them (eq. E1).

    Parameters
    ----------
    model : RobotModel with a gravity model (``links``)
    ext : Extension or Combination whose compliances bend the joints
    q : (m, n) array, commanded joint values (lateral axes 0), rad
    t : (m,) array, optional, s (for a drift part)
    iterations : int, at most this many (stops when no joint moves more than FIXED_POINT_TOL)

    Returns
    -------
    q_true : (m, n) array, rad
    tau : (m, n) array, Nm, the gravity torques at q_true
    """
    tau = gravity_torques(model, q)
    qt = ext.true_q(q, t, tau)
    for _ in range(iterations):
        tau = gravity_torques(model, qt)
        qt, prev = ext.true_q(q, t, tau), qt
        if np.abs(qt - prev).max() < FIXED_POINT_TOL:
            break
    return qt, tau


def joint_words(model: RobotModel, j: int) -> str:
    """Joint j (0-based) as every report names it, and where it is: 'joint right_3 (joint 3 of the right
    arm)' for a tree's joint named ``right_3``, 'joint 3' on a serial arm."""
    label = joint_label(j, model.joint_names)
    part, _, k = model.joint_names[j].rpartition("_")
    if part and k.isdigit() and label != f"joint {j + 1}":
        where = {"torso": "the torso"}.get(part, f"the {part} arm")
        return f"{label} (joint {k} of {where})"
    return label


def bending(model: RobotModel, ext, tau: np.ndarray) -> list[dict]:
    """Each compliance of ``ext`` with its bend at full load, largest first.

    Parameters
    ----------
    model : RobotModel
    ext : Extension or Combination
    tau : (m, n) array, Nm, the gravity torques over the poses (full load: the largest |tau_j| among them)

    Returns
    -------
    list of dict: 'joint' (name), 'axis' ('its axis', 'its x axis', ...), 'c_rad_per_nm', 'std_error',
    'full_load_nm', 'bend_mrad' and 'words' ("joint right_3 (joint 3 of the right arm) bends about its x
    axis: 0.8 mrad at full load (24 Nm)")
    """
    out = []
    for part in ext.parts:
        if part.effect not in ("joint_compliance", "lateral_compliance"):
            continue
        se = part.std_errors if part.std_errors is not None else np.full(part.size, np.nan)
        for j, c, s in zip(part.joints, part.params, se):
            i = j - 1
            lat = model.lateral_of[i] if model.lateral_of else -1
            base = lat if lat >= 0 else i
            axis = f"its {model.joint_names[i].rsplit('.', 1)[-1]} axis" if lat >= 0 else "its axis"
            load = float(np.max(np.abs(tau[:, i])))
            bend = 1e3 * abs(c) * load
            out.append(
                {
                    "joint": model.joint_names[i],
                    "axis": axis,
                    "c_rad_per_nm": float(c),
                    "std_error": float(s),
                    "full_load_nm": load,
                    "bend_mrad": bend,
                    "words": f"{joint_words(model, base)} bends about {axis}: {bend:.2f} mrad at full load "
                    f"({load:.0f} Nm; c = {c:.3g} +- {s:.2g} rad/Nm)",
                }
            )
    return sorted(out, key=lambda d: -d["bend_mrad"])
