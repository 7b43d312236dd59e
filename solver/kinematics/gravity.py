"""Static joint torques from the robot's gravity model (link masses and centres of mass).

At standstill the measured link-side joint torque (libfranka's ``tau_J``) is the gradient
of the potential energy, tau_j = dV/dq_j = sum_{i>=j} m_i g (dc_i/dq_j)_z, where
dc_i/dq_j = omega_j x c_i + v_j with (omega_j, v_j) = Ad(e^[S1]q1...e^[S(j-1)]q(j-1)) S_j,
the joint's current screw (space Jacobian column), and c_i the centre of mass of link i,
carried by the POE prefix product up to joint i.
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.errors import ModelError
from lasercal.solver.kinematics.model import Link, RobotModel
from lasercal.solver.kinematics.poe import poe_chain, space_jacobian
from lasercal.solver.kinematics.tree import ancestors, tree_frames

G = 9.81  # m/s^2; positions are in mm, so torques are divided by 1000 to give Nm


def gravity_torques(
    model: RobotModel, q: np.ndarray, payload: tuple[float, np.ndarray] | None = None
) -> np.ndarray:
    """Joint torques holding the arm still against gravity, (m, n) Nm.

    Parameters
    ----------
    model : RobotModel with ``links`` (mass kg, centre of mass at q = 0 in mm)
    q : (m, n) array, rad
    payload : (mass kg, (3,) centre of mass at q = 0 in mm) carried by the last link, optional

    Returns
    -------
    (m, n) array, Nm
    """
    if not model.links:
        raise ModelError(
            f"robot model {model.name!r} has no gravity model ('links' with masses and centres of mass)"
        )
    q = np.atleast_2d(q)
    mass = np.array([lk.mass for lk in model.links])
    com = np.array([lk.com for lk in model.links])
    if model.parents:
        return tree_gravity_torques(model, q, mass, com)
    if payload is not None:
        mass = np.r_[mass, payload[0]]
        com = np.vstack([com, payload[1]])
    owner = np.minimum(np.arange(len(mass)), model.n - 1)  # the payload rides on the last link
    chain = poe_chain(model.screws, q)  # (m, n+1, 4, 4)
    T = chain[:, owner + 1]  # each body's transform (m, b, 4, 4)
    c = np.einsum("mbij,bj->mbi", T[..., :3, :3], com) + T[..., :3, 3]  # (m, b, 3) mm
    J = space_jacobian(model.screws, chain)  # (m, 6, n)
    w, v = J[:, :3], J[:, 3:]
    # (omega_j x c_i + v_j)_z = omega_jx c_iy - omega_jy c_ix + v_jz
    dz = (
        w[:, None, 0, :] * c[:, :, 1, None] - w[:, None, 1, :] * c[:, :, 0, None] + v[:, None, 2, :]
    )  # (m, b, n)
    below = owner[:, None] >= np.arange(model.n)[None, :]  # link i moves with joint j only if i >= j
    return G / 1000.0 * np.einsum("b,mbn->mn", mass, dz * below)


def with_payload(model: RobotModel, payload: tuple[float, np.ndarray] | None) -> RobotModel:
    """``model`` whose gravity torques carry ``payload`` as :func:`gravity_torques`'s ``payload`` does: the
    last link and the payload become one body (masses added, centres of mass averaged by mass; exact, the
    torques being linear in mass times centre of mass), so that every user of ``links`` carries it.

    Parameters
    ----------
    model : RobotModel
    payload : (mass kg, (3,) centre of mass at q = 0 in mm) carried by the last link, or None

    Returns
    -------
    RobotModel: ``model`` itself without a payload, without a gravity model, or for a tree (whose torques
    :func:`gravity_torques` takes without one)
    """
    if payload is None or not model.links or model.parents:
        return model
    last, (kg, com) = model.links[-1], payload
    mass = last.mass + float(kg)
    centre = (last.mass * np.asarray(last.com, float) + float(kg) * np.asarray(com, float)) / mass
    centre.setflags(write=False)
    return model.replace(links=model.links[:-1] + (Link(mass, centre),))


def tree_gravity_torques(model: RobotModel, q: np.ndarray, mass: np.ndarray, com: np.ndarray) -> np.ndarray:
    """:func:`gravity_torques` on a tree (:mod:`solver.kinematics.tree`): body i rides on joint i's link,
    c_i = T_i(q) c_i(0), and loads joint j when j is on its path; a lateral axis's torque is the moment of
    gravity about that axis.

    Parameters
    ----------
    model : RobotModel with ``parents``
    q : (m, n) array, rad
    mass : (n,) array, kg; com : (n, 3) array, mm at q = 0, base frame

    Returns
    -------
    (m, n) array, Nm
    """
    T, J = tree_frames(model, q)
    c = np.einsum("mbij,bj->mbi", T[..., :3, :3], com) + T[..., :3, 3]  # (m, b, 3) mm
    w, v = J[:, :3], J[:, 3:]
    dz = w[:, None, 0, :] * c[:, :, 1, None] - w[:, None, 1, :] * c[:, :, 0, None] + v[:, None, 2, :]
    return G / 1000.0 * np.einsum("b,mbn->mn", mass, dz * ancestors(model)[None])


def wrist_centre(model: RobotModel) -> np.ndarray:
    """The point (3,) mm at q = 0 nearest (least squares) to the last three revolute axes: the wrist centre
    of a spherical wrist, the wrist's nearest point otherwise."""
    S = model.screws[~model.prismatic][-3:]
    w, c = S[:, :3], np.cross(S[:, :3], S[:, 3:])  # directions, points on the axes
    P = np.eye(3)[None] - w[:, :, None] * w[:, None, :]  # projectors normal to each axis
    return np.linalg.lstsq(P.sum(axis=0), np.einsum("kij,kj->i", P, c), rcond=None)[0]


def lumped_torques(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Joint torques (m, n) Nm of a 1 kg load at the wrist centre (:func:`wrist_centre`), base z up.

    For robots without a gravity model: the torques' shape over the poses is the arm's own
    weight's to first order; the unknown real load scales every joint's column, so a
    compliance fitted on these torques is the true compliance times that load (in kg).
    """
    q = np.atleast_2d(q)
    chain = poe_chain(model.screws, q)
    c = chain[:, -1, :3, :3] @ wrist_centre(model) + chain[:, -1, :3, 3]  # (m, 3) mm
    J = space_jacobian(model.screws, chain)
    dz = J[:, 0, :] * c[:, 1, None] - J[:, 1, :] * c[:, 0, None] + J[:, 5, :]  # (omega_j x c + v_j)_z
    return G / 1000.0 * dz


def model_torques(model: RobotModel, q: np.ndarray) -> tuple[np.ndarray, str]:
    """The robot's gravity torques (m, n) Nm when it has a gravity model, else :func:`lumped_torques`;
    and which of the two ('gravity model' or 'lumped load at the wrist centre')."""
    if model.links:
        return gravity_torques(model, q), "gravity model"
    return lumped_torques(model, q), "lumped load at the wrist centre"
