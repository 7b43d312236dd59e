"""Aiming inverse kinematics: configurations whose beam passes through a point.

The beam through a point is 2 constraints, so a 6- or 7-joint arm has a 4- or
5-dimensional family of solutions. To get *diverse* poses (what calibration needs) we
(1) draw many random beam poses -- a tilt within a cone about straight down, an azimuth,
a laser length -- and random seeds near the model's home configuration, (2) solve the
5-constraint pose problem (aperture position, beam direction) for all of them at once by
damped least squares, (3) polish each solution onto the exact 2-constraint manifold with
minimum-norm Newton steps, and (4) keep the in-limit solutions that are farthest apart in
joint space (greedy farthest-point selection).
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.errors import AimingError
from lasercal.solver.kinematics.laser import beam, beam_joint_jacobian, plane_hit, spot_joint_jacobian
from lasercal.solver.kinematics.model import RobotModel


def _dls_step(J: np.ndarray, r: np.ndarray, damping: float) -> np.ndarray:
    """Damped least-squares step dq = J^T (J J^T + l^2 I)^-1 r, batched: J (m, k, n), r (m, k)."""
    k = J.shape[1]
    JJt = J @ np.swapaxes(J, 1, 2) + damping**2 * np.eye(k)
    return np.einsum("mkn,mk->mn", J, np.linalg.solve(JJt, r[..., None])[..., 0])


def spot_error(model: RobotModel, q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """In-plane distance (m,) between the model's spot and the point (on the plane z = point_z), mm."""
    b = beam(model.screws, model.laser_dir, model.aperture, q)
    spot, t = plane_hit(b.aperture, b.direction, point[2])
    return np.where(t > 0, np.linalg.norm(spot[:, :2] - point[:2], axis=1), np.inf)


def polish(model: RobotModel, q: np.ndarray, point: np.ndarray, iters: int = 8) -> np.ndarray:
    """Minimum-norm Newton steps onto the set of configurations whose spot is exactly the point.

    Parameters
    ----------
    model : RobotModel
    q : (m, n) array, configurations near the solution set, rad
    point : (3,) or (m, 3) array, the target (per configuration), mm

    Returns
    -------
    (m, n) array
    """
    q = np.array(q, dtype=float)
    point = np.broadcast_to(np.asarray(point, dtype=float), (len(q), 3))
    for _ in range(iters):
        spot, Js = spot_joint_jacobian(model, q, point[:, 2])
        q = q + _dls_step(Js, point[:, :2] - spot[:, :2], 1e-9)
    return q


def aim(
    model: RobotModel,
    point,
    n: int,
    rng: np.random.Generator,
    tilt: tuple[float, float] = (0.0, np.radians(35)),
    length: tuple[float, float] = (150.0, 600.0),
    seed_spread: float = 0.6,
    margin: float = 0.05,
    pool: int | None = None,
) -> np.ndarray:
    """N diverse in-limit configurations whose beam passes exactly through ``point``.

    Parameters
    ----------
    model : RobotModel, the robot whose beam is aimed (truth for a simulation, the
        identified model for a validation run)
    point : (3,) array, the target on the plane, mm, base frame
    n : int, number of configurations
    rng : numpy Generator
    tilt : (min, max), range of the beam's angle from straight down, rad
    length : (min, max), laser length range, mm
    seed_spread : float, std of the random seeds about ``model.home``, rad
    margin : float, distance kept from every joint limit, rad
    pool : int, candidates drawn before the diverse selection (default 8 n)

    Returns
    -------
    (n, joints) array, rad

    Raises
    ------
    AimingError
        When fewer than n in-limit solutions were found.
    """
    point = np.asarray(point, dtype=float)
    nj = model.n
    pool = pool or max(8 * n, 64)
    lo, hi = model.limits[:, 0] + margin, model.limits[:, 1] - margin
    home = model.home if model.home is not None else (lo + hi) / 2
    found = np.empty((0, nj))
    for _ in range(6):  # a few rounds in case many candidates fail
        c = rng.uniform(np.cos(tilt[1]), np.cos(tilt[0]), pool)  # uniform over the spherical zone
        th = np.arccos(c)
        az = rng.uniform(0, 2 * np.pi, pool)
        d_star = np.stack([np.sin(th) * np.cos(az), np.sin(th) * np.sin(az), -c], axis=1)
        a_star = point - rng.uniform(*length, pool)[:, None] * d_star
        q = np.clip(home + rng.normal(0, seed_spread, (pool, nj)), lo, hi)
        for _ in range(60):
            b, da, dd = beam_joint_jacobian(model, q)
            r = np.concatenate([a_star - b.aperture, 300.0 * (d_star - b.direction)], axis=1)
            J = np.concatenate([da, 300.0 * dd], axis=1)  # direction weighted as a 300 mm lever
            q = np.clip(q + _dls_step(J, r, 5.0), lo, hi)
        q = polish(model, q, point)
        ok = model.within_limits(q, margin=margin * 0.5) & (spot_error(model, q, point) < 1e-7)
        b = beam(model.screws, model.laser_dir, model.aperture, q)
        ok &= -b.direction[:, 2] > np.cos(
            min(tilt[1] + np.radians(10), np.pi / 2 - 1e-3)
        )  # beam still points down
        found = np.concatenate([found, q[ok]])
        if len(found) >= 2 * n:
            break
    if len(found) < n:
        raise AimingError(f"only {len(found)} of {n} in-limit configurations aim at {point.tolist()} mm")
    return found[_farthest_points(found, n, rng)]


def _farthest_points(q: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of n rows of q chosen greedily to maximise the smallest joint-space distance."""
    idx = [int(rng.integers(len(q)))]
    dmin = np.linalg.norm(q - q[idx[0]], axis=1)
    for _ in range(n - 1):
        k = int(np.argmax(dmin))
        idx.append(k)
        dmin = np.minimum(dmin, np.linalg.norm(q - q[k], axis=1))
    return np.array(idx)
