"""The robot with a laser pointer: the laser as a prismatic joint (thesis Section 3.1).

Forward model (eq. 3.1.1, 3.1.4): with E(q) = e^[S1]q1 ... e^[Sn]qn, the aperture is at
a = E p_M, the beam points along d = R_E v_p, and the tip at laser length t is
p_t = E (p_M + t v_p). The spot on a horizontal plane z = z0 is the tip at
t = (z0 - a_z) / d_z.

Parametrisation (minimal POE, Section 2.2.2): x = [eta_1 (4), ..., eta_n (4),
eta_p (2), p_M (3)] with link frames fixed at a reference model, so eta = 0 there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.kinematics.minimal import link_frame, screw_from_eta
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import adjoint, dexp_A, poe_chain, space_jacobian


@dataclass(frozen=True)
class Beam:
    """The beam of m configurations.

    Attributes
    ----------
    chain : (m, n + 1, 4, 4) array, prefix products of the POE formula
    aperture : (m, 3) array, mm
    direction : (m, 3) array, unit
    """

    chain: np.ndarray
    aperture: np.ndarray
    direction: np.ndarray


def beam(screws: np.ndarray, laser_dir: np.ndarray, aperture: np.ndarray, q: np.ndarray) -> Beam:
    """Aperture and beam direction in the base frame (eq. 3.1.4 with the laser length split off).

    Parameters
    ----------
    screws : (n, 6) array
    laser_dir : (3,) array, v_p
    aperture : (3,) array, p_M, mm
    q : (m, n) array, rad

    Returns
    -------
    Beam
    """
    chain = poe_chain(screws, q)
    E = chain[:, -1]
    a = E[:, :3, :3] @ aperture + E[:, :3, 3]
    d = E[:, :3, :3] @ laser_dir
    return Beam(chain, a, d)


def plane_hit(a: np.ndarray, d: np.ndarray, z: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Where the beam a + t d meets the plane z = z0.

    Parameters
    ----------
    a, d : (m, 3) arrays, aperture (mm) and unit direction
    z : float or (m,) array, plane height, mm

    Returns
    -------
    spot : (m, 3) array, mm
    length : (m,) array, the laser length t (mm); negative when the plane is behind the aperture
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.asarray(z, dtype=float) - a[:, 2]) / d[:, 2]
    return a + t[:, None] * d, t


def beam_joint_jacobian(model: RobotModel, q: np.ndarray) -> tuple[Beam, np.ndarray, np.ndarray]:
    """Beam and the joint Jacobians of its aperture and direction.

    With (omega_j, v_j) the space-Jacobian column of joint j: da/dq_j = omega_j x a + v_j,
    dd/dq_j = omega_j x d.

    Returns
    -------
    Beam, da/dq (m, 3, n) array (mm/rad), dd/dq (m, 3, n) array (1/rad)
    """
    b = beam(model.screws, model.laser_dir, model.aperture, q)
    J = space_jacobian(model.screws, b.chain)
    w, v = J[:, :3], J[:, 3:]
    return b, np.cross(w, b.aperture[:, :, None], axis=1) + v, np.cross(w, b.direction[:, :, None], axis=1)


def spot_joint_jacobian(model: RobotModel, q: np.ndarray, z) -> tuple[np.ndarray, np.ndarray]:
    """Spots on the plane z and their joint Jacobian d(spot_xy)/dq.

    Returns
    -------
    spot : (m, 3) array, mm
    J : (m, 2, n) array, mm/rad
    """
    b, da, dd = beam_joint_jacobian(model, q)
    spot, t = plane_hit(b.aperture, b.direction, z)
    return spot, project_to_plane(da + t[:, None, None] * dd, b.direction)


def tip_jacobian_columns(
    b: Beam, twists: np.ndarray, dd: np.ndarray, da: np.ndarray, length: np.ndarray
) -> np.ndarray:
    """Tip displacement per parameter: dp_t = [-[p_t], I] xi + R_h dp_M (eqs. 3.1.6, 3.1.11-3.1.12).

    Written as dp_t = (w x a + v + R_E da) + t (w x d + R_E dd), which is the same thing
    for p_t = a + t d.

    Parameters
    ----------
    b : Beam
    twists : (m, 6, k) array, spatial twists of the joint-screw parameters
    dd : (3, j) array, derivative of v_p (before the rotation R_E)
    da : (3, l) array, derivative of p_M (before the rotation R_E)
    length : (m,) array, laser length t

    Returns
    -------
    (m, 3, k + j + l) array
    """
    w, v = twists[:, :3, :], twists[:, 3:, :]
    a, d = b.aperture[:, :, None], b.direction[:, :, None]
    t = length[:, None, None]
    uj = np.cross(w, a, axis=1) + v + t * np.cross(w, d, axis=1)
    R = b.chain[:, -1, :3, :3]
    up = t * (R @ dd)
    um = R @ da
    return np.concatenate([uj, np.broadcast_to(up, (len(t),) + up.shape[1:]), um], axis=2)


def project_to_plane(u: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Spot displacement in the plane from a tip displacement with the laser length free.

    Moving the tip by u while the plane is fixed slides the spot along the beam back to
    the plane: d(spot)_xy = u_xy - (d_xy / d_z) u_z.

    Parameters
    ----------
    u : (m, 3, p) array
    d : (m, 3) array, beam directions

    Returns
    -------
    (m, 2, p) array
    """
    return u[:, :2, :] - (d[:, :2] / d[:, 2:3])[:, :, None] * u[:, 2:3, :]


class LaserParams:
    """Minimal-POE parameter vector of a laser robot, with link frames fixed at a reference model.

    Parameters
    ----------
    model : RobotModel, the reference (eta = 0 and p_M = model.aperture at x = 0)
    """

    def __init__(self, model: RobotModel):
        self.model = model
        self.frames = [link_frame(S) for S in model.screws]
        self.laser_frame = link_frame(np.concatenate([np.zeros(3), model.laser_dir]))
        n = model.n
        self.n_joint = 4 * n
        self.size = 4 * n + 2 + 3
        self.names = [f"{jn}.{p}" for jn in model.joint_names for p in ("wx", "wy", "qx", "qy")]
        self.names += ["laser.vx", "laser.vy", "M.x", "M.y", "M.z"]
        self.kinds = ["axis", "axis", "offset", "offset"] * n + ["laser"] * 2 + ["aperture"] * 3
        self.slice_laser = slice(4 * n, 4 * n + 2)
        self.slice_M = slice(4 * n + 2, 4 * n + 5)

    def x0(self) -> np.ndarray:
        """The parameter vector of the reference model."""
        x = np.zeros(self.size)
        x[self.slice_M] = self.model.aperture
        return x

    def geometry(self, x: np.ndarray):
        """Screws, laser direction and aperture at x, with their derivatives.

        Returns
        -------
        screws : (n, 6) array
        dscrews : list of n (6, 4) arrays
        laser_dir : (3,) array
        dlaser : (3, 2) array
        aperture : (3,) array
        """
        screws, dscrews = [], []
        for i, T in enumerate(self.frames):
            S, dS = screw_from_eta(T, x[4 * i : 4 * i + 4])
            screws.append(S)
            dscrews.append(dS)
        Sp, dSp = screw_from_eta(self.laser_frame, x[self.slice_laser])
        return np.array(screws), dscrews, Sp[3:], dSp[3:], x[self.slice_M].copy()

    def to_model(self, x: np.ndarray, **changes) -> RobotModel:
        """The robot model at x."""
        screws, _, vp, _, pM = self.geometry(x)
        return self.model.replace(screws=screws, laser_dir=vp, aperture=pM, **changes)

    def beam(self, x: np.ndarray, q: np.ndarray) -> Beam:
        """The beam of configurations q under parameters x."""
        screws, _, vp, _, pM = self.geometry(x)
        return beam(screws, vp, pM, q)

    def _twists(self, x: np.ndarray, q: np.ndarray):
        """Beam, spatial twists of the joint parameters (eq. 2.3.28) and dv_p/deta_p."""
        screws, dscrews, vp, dvp, pM = self.geometry(x)
        b = beam(screws, vp, pM, q)
        twists = np.concatenate(
            [adjoint(b.chain[:, i]) @ (dexp_A(screws[i], q[:, i]) @ dscrews[i]) for i in range(len(screws))],
            axis=2,
        )
        return b, twists, dvp

    def tip_jacobian(self, x: np.ndarray, q: np.ndarray, length: np.ndarray) -> tuple[Beam, np.ndarray]:
        """Beam and the tip Jacobian K at laser lengths ``length`` (eqs. 3.1.9-3.1.13).

        Returns
        -------
        Beam, and (m, 3, size) array
        """
        b, twists, dvp = self._twists(x, q)
        return b, tip_jacobian_columns(b, twists, dvp, np.eye(3), length)

    def spots(self, x: np.ndarray, q: np.ndarray, z: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Spots (m, 3) and laser lengths (m,) on the plane(s) z for parameters x."""
        b = self.beam(x, q)
        return plane_hit(b.aperture, b.direction, z)

    def spot_jacobian(
        self, x: np.ndarray, q: np.ndarray, z: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Spots (m, 3), laser lengths (m,) and the in-plane spot Jacobian (m, 2, size)."""
        b, twists, dvp = self._twists(x, q)
        spot, t = plane_hit(b.aperture, b.direction, z)
        K = tip_jacobian_columns(b, twists, dvp, np.eye(3), t)
        return spot, t, project_to_plane(K, b.direction)

    def line_jacobian(
        self, x: np.ndarray, q: np.ndarray, target: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Perpendicular offset of each target from its beam, and its Gauss-Newton Jacobian.

        r = (I - d d^T)(P - a): the target's offset from the closest point of the beam, at
        laser length t* = d.(P - a). Unlike the in-plane spot error it is not amplified by
        1/cos(tilt) on steep beams, so it is the better-behaved residual far from the solution.
        The Jacobian -(I - d d^T) dp_t(t*) drops a term proportional to r, exact at r = 0.

        Returns
        -------
        r : (m, 3) array, mm
        J : (m, 3, size) array
        """
        b, twists, dvp = self._twists(x, q)
        a, d = b.aperture, b.direction
        t = np.sum(d * (target - a), axis=1)
        r = target - a - t[:, None] * d
        u = tip_jacobian_columns(b, twists, dvp, np.eye(3), t)
        proj = np.eye(3) - d[:, :, None] * d[:, None, :]
        return r, -proj @ u
