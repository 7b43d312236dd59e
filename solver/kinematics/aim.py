"""Aiming inverse kinematics: configurations whose beam passes through a point.

The beam through a point is 2 constraints, so a 6- or 7-joint arm has a 4- or
5-dimensional family of solutions. To get *diverse* poses (what calibration needs) we
(1) draw many random beam poses -- a tilt within a cone about straight down, an azimuth,
a laser length -- and random seeds near the model's home configuration, (2) solve the
5-constraint pose problem (aperture position, beam direction) for all of them at once by
Levenberg-Marquardt, then move to the solution nearest each seed (a fixed point that depends on the
seed, not on the path: a seeded aim is the same on every CPU), (3) polish each solution onto the
exact 2-constraint manifold with minimum-norm Newton steps, and (4) keep the in-limit solutions that
are farthest apart in joint space (greedy farthest-point selection).
"""

from __future__ import annotations

import threading

import numpy as np

from lasercal.solver.errors import AimingError
from lasercal.solver.kinematics.laser import beam, beam_joint_jacobian, plane_hit, spot_joint_jacobian
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.streams import Seed, root, stream


def _dls_step(J: np.ndarray, r: np.ndarray, damping) -> np.ndarray:
    """Damped least-squares step dq = J^T (J J^T + l^2 I)^-1 r, batched: J (m, k, n), r (m, k), l a
    float or (m,) array."""
    k = J.shape[1]
    JJt = J @ np.swapaxes(J, 1, 2) + (np.asarray(damping, dtype=float) ** 2)[..., None, None] * np.eye(k)
    return np.einsum("mkn,mk->mn", J, np.linalg.solve(JJt, r[..., None])[..., 0])


def spot_error(model: RobotModel, q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """In-plane distance (m,) between the model's spot and the point (on the plane z = point_z), mm."""
    b = beam(model.screws, model.laser_dir, model.aperture, q)
    spot, t = plane_hit(b.aperture, b.direction, point[2])
    return np.where(t > 0, np.linalg.norm(spot[:, :2] - point[:2], axis=1), np.inf)


def polish(
    model: RobotModel, q: np.ndarray, point: np.ndarray, tol: float = 1e-12, max_iter: int = 30
) -> np.ndarray:
    """Minimum-norm Newton steps onto the set of configurations whose spot is exactly the point.

    Each configuration steps until its step is below ``tol`` (quadratic convergence: a few steps),
    not a fixed count, so that where it stops does not depend on the last bit of a step.

    Parameters
    ----------
    model : RobotModel
    q : (m, n) array, configurations near the solution set, rad
    point : (3,) or (m, 3) array, the target (per configuration), mm
    tol : float, largest joint step at which a configuration has arrived, rad
    max_iter : int, most steps

    Returns
    -------
    (m, n) array
    """
    q = np.array(q, dtype=float)
    point = np.broadcast_to(np.asarray(point, dtype=float), (len(q), 3))
    active = np.arange(len(q))
    for _ in range(max_iter):
        if not len(active):
            break
        spot, Js = spot_joint_jacobian(model, q[active], point[active, 2])
        dq = _dls_step(Js, point[active, :2] - spot[:, :2], 1e-9)
        q[active] += dq
        active = active[~(np.abs(dq).max(axis=1) < tol)]  # NaN (a beam along the plane) stops too
    return q


def _beam_residual(model: RobotModel, q, a_star, d_star) -> tuple[np.ndarray, np.ndarray]:
    """Beam-pose residual r = (a* - a(q), L (d* - d(q))) (m, 6) and its joint Jacobian (m, 6, n); L = 300 mm
    weighs the direction as a 300 mm lever."""
    b, da, dd = beam_joint_jacobian(model, q)
    r = np.concatenate([a_star - b.aperture, 300.0 * (d_star - b.direction)], axis=1)
    return r, np.concatenate([da, 300.0 * dd], axis=1)


def _reach_beams(
    model: RobotModel, q: np.ndarray, a_star: np.ndarray, d_star: np.ndarray, lo, hi, max_iter: int = 150
) -> tuple[np.ndarray, np.ndarray]:
    """Levenberg-Marquardt towards the beam poses (aperture a*, direction d*), inside the box [lo, hi].

    A step dq = J^T (J J^T + mu I)^-1 r (r, J of :func:`_beam_residual`), clipped into the box, is taken
    only where it lowers |r|; mu shrinks after a taken step and grows after a refused one, per
    configuration (a fixed count of undamped steps bounced off the limits chaotically). A configuration
    stops when its step is below 1e-10 rad or mu has grown past 1e12 mm^2 (a local minimum).

    Returns
    -------
    q : (m, n) array, rad
    converged : (m,) bool array
    """
    m = len(q)
    mu = np.full(m, 25.0)
    r, J = _beam_residual(model, q, a_star, d_star)
    cost = np.sum(r**2, axis=1)
    converged = np.zeros(m, dtype=bool)
    active = np.arange(m)
    for _ in range(max_iter):
        if not len(active):
            break
        k = active
        dq = _dls_step(J[k], r[k], np.sqrt(mu[k]))
        q_new = np.clip(q[k] + dq, lo, hi)
        r_new, J_new = _beam_residual(model, q_new, a_star[k], d_star[k])
        cost_new = np.sum(r_new**2, axis=1)
        take = cost_new < cost[k]
        t = k[take]
        q[t], r[t], J[t], cost[t] = q_new[take], r_new[take], J_new[take], cost_new[take]
        mu[k] = np.where(take, np.maximum(mu[k] / 3.0, 1e-6), mu[k] * 4.0)
        done = (take & (np.abs(dq).max(axis=1) < 1e-10)) | (mu[k] > 1e12)
        converged[k[done]] = True
        active = k[~done]
    return q, converged


def _nearest_on_beams(
    model: RobotModel, q, q_seed, a_star, d_star, lo, hi, max_pull: float = 0.1, max_iter: int = 100
) -> tuple[np.ndarray, np.ndarray]:
    """The configurations on the beam poses nearest their seeds: min |q - q_s| subject to r(q) = 0.

    Gauss-Newton on the constrained problem (the null-space form of eq. 6.7 in Modern Robotics):
    dq = J^+ r + (I - J^+ J)(q_s - q), the pull shortened to ``max_pull`` rad per joint, clipped into
    the box; J^+ from an SVD (J has rank 5: the direction is a unit vector). Its fixed point is a
    function of the seed and the beam pose alone, well conditioned, whatever path the descent of
    :func:`_reach_beams` took to the solution set -- that path amplifies a last-bit difference a
    millionfold. A configuration stops when its step is below 1e-12 rad.

    Returns
    -------
    q : (m, n) array, rad
    converged : (m,) bool array
    """
    m = len(q)
    converged = np.zeros(m, dtype=bool)
    active = np.arange(m)
    for _ in range(max_iter):
        if not len(active):
            break
        k = active
        r, J = _beam_residual(model, q[k], a_star[k], d_star[k])
        Jp = np.linalg.pinv(J, rcond=1e-10)
        pull = q_seed[k] - q[k]
        null = pull - np.einsum("mnk,mkj,mj->mn", Jp, J, pull)
        big = np.abs(null).max(axis=1, keepdims=True)
        dq = np.einsum("mnk,mk->mn", Jp, r) + null * np.minimum(1.0, max_pull / np.maximum(big, 1e-300))
        q[k] = np.clip(q[k] + dq, lo, hi)
        done = np.abs(dq).max(axis=1) < 1e-12
        converged[k[done]] = True
        active = k[~done]
    return q, converged


def beam_reach(model: RobotModel, length: float) -> tuple[np.ndarray, float] | None:
    """A bound on how far from joint 1's axis a beam of up to ``length`` mm can reach, whatever the angles.

    With p_i a point on joint i's axis at q = 0 (p_1 the axis's point nearest the base origin, each next
    one the foot of the previous on its axis), turning joint i moves p_(i+1) about an axis through p_i and
    every earlier joint moves both rigidly, so |p_(i+1) - p_i| never changes; by the triangle inequality
    |spot - p_1| <= sum_i |p_(i+1) - p_i| + |aperture - p_n| + length.

    Parameters
    ----------
    model : RobotModel, revolute joints
    length : float, the longest beam, mm

    Returns
    -------
    (p_1 (3,) mm, bound mm), or None for a robot with a prismatic joint (no such bound)
    """
    if np.any(model.prismatic):
        return None
    w, v = model.screws[:, :3], model.screws[:, 3:]
    on_axis = np.cross(w, v) / np.sum(w * w, axis=1)[:, None]  # v = -w x q: the axis point nearest the origin
    pts = [on_axis[0]]
    for i in range(1, model.n):  # the foot of the previous point on this axis
        u = w[i] / np.linalg.norm(w[i])
        pts.append(on_axis[i] + np.dot(pts[-1] - on_axis[i], u) * u)
    pts.append(np.asarray(model.aperture, dtype=float))
    return pts[0], float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)) + length)


def aim(
    model: RobotModel,
    point,
    n: int,
    rng: Seed,
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
    rng : int, SeedSequence or Generator: the root of this call's streams (:mod:`solver.streams`);
        each round of candidates and the selection draw from a stream of their own
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
    far = beam_reach(model, length[1])
    if far is not None and np.linalg.norm(point - far[0]) > far[1]:  # no IK needed to say so
        raise AimingError(
            f"{point.tolist()} mm lies {np.linalg.norm(point - far[0]):.0f} mm from joint 1's axis point, "
            f"beyond what the arm and a beam of {length[1]:g} mm can reach ({far[1]:.0f} mm)"
        )
    seed = root(rng)
    key = _aim_key(model, point, n, seed, tilt, length, seed_spread, margin, pool)
    with _AIMED_LOCK:
        found = _AIMED.get(key)
    if found is None:
        try:
            found = _aim(model, point, n, seed, tilt, length, seed_spread, margin, pool)
        except AimingError as e:
            found = str(e)
        with _AIMED_LOCK:
            _AIMED[key] = found
            while len(_AIMED) > _AIMED_MAX:
                del _AIMED[next(iter(_AIMED))]  # the oldest
    if isinstance(found, str):
        raise AimingError(found)
    return found.copy()  # the caller's to change


# The aims made so far in this process (their configurations, or why none was found), by everything an
# aim is a function of (:func:`_aim_key`): a session's coach, the same session resumed, a simulation and
# its reruns aim at what they aimed at before, 0.1-1 s each time. What they get is what a new aim would
# give, bit for bit.
_AIMED: dict = {}
_AIMED_MAX = 4096
_AIMED_LOCK = threading.Lock()


def _aim_key(model: RobotModel, point, n, seed, tilt, length, seed_spread, margin, pool) -> tuple:
    """What :func:`aim` reads: the arm's screws, laser, limits and home, the point, the root seed and the
    options, as bytes, numbers and the seed's repr."""
    arrays = (model.screws, model.laser_dir, model.aperture, model.limits, point, tilt, length)
    home = None if model.home is None else np.asarray(model.home, dtype=float).tobytes()
    seed_words = repr((seed.entropy, seed.spawn_key, seed.pool_size))
    return (
        tuple(np.asarray(a, dtype=float).tobytes() for a in arrays),
        home,
        int(n),
        seed_words,
        float(seed_spread),
        float(margin),
        pool,
    )


def _aim(
    model: RobotModel,
    point: np.ndarray,
    n: int,
    seed: np.random.SeedSequence,
    tilt: tuple[float, float],
    length: tuple[float, float],
    seed_spread: float,
    margin: float,
    pool: int | None,
) -> np.ndarray:
    """:func:`aim` from its root seed, not remembered."""
    nj = model.n
    pool = pool or max(8 * n, 64)
    lo, hi = model.limits[:, 0] + margin, model.limits[:, 1] - margin
    home = model.home if model.home is not None else (lo + hi) / 2
    found = np.empty((0, nj))
    for round_ in range(6):  # a few rounds in case many candidates fail
        draw = stream(seed, "round", round_)
        c = draw.uniform(np.cos(tilt[1]), np.cos(tilt[0]), pool)  # uniform over the spherical zone
        th = np.arccos(c)
        az = draw.uniform(0, 2 * np.pi, pool)
        d_star = np.stack([np.sin(th) * np.cos(az), np.sin(th) * np.sin(az), -c], axis=1)
        a_star = point - draw.uniform(*length, pool)[:, None] * d_star
        q_seed = np.clip(home + draw.normal(0, seed_spread, (pool, nj)), lo, hi)
        q, reached = _reach_beams(model, q_seed.copy(), a_star, d_star, lo, hi)
        q, converged = _nearest_on_beams(model, q, q_seed, a_star, d_star, lo, hi)
        converged &= reached
        q = polish(model, q, point)
        # decisions with margins far wider than round-off: a polished pose misses by ~1e-13 mm or by far
        ok = converged & model.within_limits(q, margin=margin * 0.5) & (spot_error(model, q, point) < 1e-7)
        b = beam(model.screws, model.laser_dir, model.aperture, q)
        ok &= -b.direction[:, 2] > np.cos(
            min(tilt[1] + np.radians(10), np.pi / 2 - 1e-3)
        )  # beam still points down
        found = np.concatenate([found, q[ok]])
        if len(found) >= 2 * n:
            break
    if len(found) < n:
        raise AimingError(f"only {len(found)} of {n} in-limit configurations aim at {point.tolist()} mm")
    return found[_farthest_points(found, n, stream(seed, "select"))]


def _farthest_points(q: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Indices of n rows of q chosen greedily to maximise the smallest joint-space distance."""
    idx = [int(rng.integers(len(q)))]
    dmin = np.linalg.norm(q - q[idx[0]], axis=1)
    for _ in range(n - 1):
        k = int(np.argmax(dmin))
        idx.append(k)
        dmin = np.minimum(dmin, np.linalg.norm(q - q[k], axis=1))
    return np.array(idx)
