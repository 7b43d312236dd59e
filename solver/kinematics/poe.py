"""Lie-group kinematics of the product-of-exponentials (POE) formula.

Conventions (used by every module of ``solver``):

* A screw or twist is a 6-vector ordered **(omega, v)** -- angular part first -- as in
  the thesis (eq. 2.1.9) and Modern Robotics.
* Lengths in mm, angles in rad.
* Functions are vectorised: leading axes broadcast, so ``q`` shaped ``(m, n)`` gives
  ``m`` poses at once.

Equation numbers refer to the thesis (P. Detdee, SNU 2019).
"""

from __future__ import annotations

import numpy as np

# Below this angle the closed forms lose digits (1 - cos t: about 1e-16 / t^2 relative, 2e-4 at t = 1e-6 -- a
# 1e-8 mm error hypothesis found in log6(exp6(xi))); their Taylor series to t^4 are exact to 1e-22 there.
_SMALL = 1e-3


def skew(w: np.ndarray) -> np.ndarray:
    """The so(3) matrix [w] of a 3-vector (eq. 2.1.4).

    Parameters
    ----------
    w : (..., 3) array

    Returns
    -------
    (..., 3, 3) array
    """
    w = np.asarray(w, dtype=float)
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -w[..., 2], w[..., 1]
    out[..., 1, 0], out[..., 1, 2] = w[..., 2], -w[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -w[..., 1], w[..., 0]
    return out


def exp6(xi: np.ndarray) -> np.ndarray:
    """Matrix exponential e^[xi] of a twist xi = S*theta (eqs. 2.1.3, 2.1.5, 2.1.6).

    Valid for any twist, unit or not: with a unit omega this is exactly
    R = I + sin(t)[w] + (1-cos(t))[w]^2 and p = G(t) v of the thesis.

    Parameters
    ----------
    xi : (..., 6) array, (omega, v), rad and mm

    Returns
    -------
    (..., 4, 4) array, homogeneous transforms
    """
    xi = np.asarray(xi, dtype=float)
    wx, wy, wz, vx, vy, vz = np.moveaxis(xi, -1, 0).copy()  # contiguous components: element-wise ops run fast
    t2 = wx * wx + wy * wy + wz * wz
    t = np.sqrt(t2)
    small = t < _SMALL
    ts = np.where(small, 1.0, t)
    sin, cos = np.sin(ts), np.cos(ts)
    a = np.where(small, 1 - t2 / 6 + t2**2 / 120, sin / ts)
    b = np.where(small, 0.5 - t2 / 24 + t2**2 / 720, (1 - cos) / ts**2)
    c = np.where(small, 1 / 6 - t2 / 120 + t2**2 / 5040, (ts - sin) / ts**3)
    # [w]^2 = w w^T - |w|^2 I, so R = I + a[w] + b[w]^2 and p = (I + b[w] + c[w]^2) v element by element:
    # no batched 3x3 products (most of the time of a tree's Jacobian went to them)
    d, e, cwv = 1 - b * t2, 1 - c * t2, c * (wx * vx + wy * vy + wz * vz)
    bxy, bxz, byz = b * wx * wy, b * wx * wz, b * wy * wz
    ax, ay, az = a * wx, a * wy, a * wz
    zero, one = np.zeros_like(t), np.ones_like(t)
    T = np.stack(  # built entry-major, then one transposing copy
        [
            d + b * wx * wx, bxy - az, bxz + ay, e * vx + b * (wy * vz - wz * vy) + cwv * wx,
            bxy + az, d + b * wy * wy, byz - ax, e * vy + b * (wz * vx - wx * vz) + cwv * wy,
            bxz - ay, byz + ax, d + b * wz * wz, e * vz + b * (wx * vy - wy * vx) + cwv * wz,
            zero, zero, zero, one,
        ],
    )  # fmt: skip
    return np.ascontiguousarray(np.moveaxis(T, 0, -1)).reshape(xi.shape[:-1] + (4, 4))


def log6(T: np.ndarray) -> np.ndarray:
    """Matrix logarithm of a rigid transform, as a twist (the inverse of :func:`exp6`).

    The rotation part uses scipy's rotation vector (robust near pi); the translation
    part inverts G (eq. 2.1.6).

    Parameters
    ----------
    T : (..., 4, 4) array

    Returns
    -------
    (..., 6) array, (omega*theta, v*theta)
    """
    from scipy.spatial.transform import Rotation  # loaded on use: slow to import at start-up

    T = np.asarray(T, dtype=float)
    lead = T.shape[:-2]
    R = T[..., :3, :3].reshape(-1, 3, 3)
    w = Rotation.from_matrix(R).as_rotvec().reshape(lead + (3,))
    t = np.linalg.norm(w, axis=-1)
    small = t < _SMALL
    ts = np.where(small, 1.0, t)
    k = np.where(small, 1 / 12 + t**2 / 720 + t**4 / 30240, (1 - ts / 2 / np.tan(ts / 2)) / ts**2)
    W = skew(w)
    Vinv = np.eye(3) - W / 2 + k[..., None, None] * (W @ W)
    v = np.einsum("...ij,...j->...i", Vinv, T[..., :3, 3])
    return np.concatenate([w, v], axis=-1)


def inv_T(T: np.ndarray) -> np.ndarray:
    """Inverse of homogeneous transforms, (..., 4, 4) -> (..., 4, 4)."""
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def adjoint(T: np.ndarray) -> np.ndarray:
    """Adjoint representation [Ad_T] for (omega, v) screws (eq. 2.1.11).

    Parameters
    ----------
    T : (..., 4, 4) array

    Returns
    -------
    (..., 6, 6) array, [[R, 0], [[p]R, R]]
    """
    T = np.asarray(T, dtype=float)
    R, p = T[..., :3, :3], T[..., :3, 3]
    out = np.zeros(T.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., 3:, :3] = skew(p) @ R
    return out


def ad(S: np.ndarray) -> np.ndarray:
    """Lie bracket matrix Omega = ad_S = [[[w], 0], [[v], [w]]] (defined below eq. 2.3.26).

    Parameters
    ----------
    S : (..., 6) array

    Returns
    -------
    (..., 6, 6) array
    """
    S = np.asarray(S, dtype=float)
    out = np.zeros(S.shape[:-1] + (6, 6))
    W = skew(S[..., :3])
    out[..., :3, :3] = W
    out[..., 3:, 3:] = W
    out[..., 3:, :3] = skew(S[..., 3:])
    return out


def dexp_A(S: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The matrix A with [(d e^[S]theta) e^-[S]theta]^vee = A dS, theta fixed (eq. 2.3.26).

    The thesis prints A for a revolute joint with |omega| kept general, and A = theta*I
    for a prismatic joint; both are the closed form of sum_k theta^(k+1) Omega^k/(k+1)!.
    For a prismatic joint Omega^2 = 0, so the series stops after the Omega term, which
    (unlike the printed theta*I) also covers perturbations dS with a rotational part.

    Parameters
    ----------
    S : (6,) array, the screw (unit omega, or omega = 0)
    theta : (m,) array, joint values (rad, or mm for a prismatic joint)

    Returns
    -------
    (m, 6, 6) array
    """
    S = np.asarray(S, dtype=float)
    th = np.asarray(theta, dtype=float)
    O1 = ad(S)
    O2 = O1 @ O1
    O3 = O2 @ O1
    O4 = O3 @ O1
    n = float(np.linalg.norm(S[:3]))
    a = n * th
    if n < _SMALL:  # prismatic: the series is exact after two terms
        c1, c2, c3, c4 = th**2 / 2, th**3 / 6, th**4 / 24, th**5 / 120
    else:
        small = np.abs(a) < 1e-3
        asafe = np.where(small, 1.0, a)
        s, c = np.sin(asafe), np.cos(asafe)
        c1 = np.where(small, th**2 / 2, (4 - asafe * s - 4 * c) / (2 * n**2))
        c2 = np.where(small, th**3 / 6, (4 * asafe - 5 * s + asafe * c) / (2 * n**3))
        c3 = np.where(small, th**4 / 24, (2 - asafe * s - 2 * c) / (2 * n**4))
        c4 = np.where(small, th**5 / 120, (2 * asafe - 3 * s + asafe * c) / (2 * n**5))
    A = th[:, None, None] * np.eye(6)
    for ck, Ok in ((c1, O1), (c2, O2), (c3, O3), (c4, O4)):
        A = A + ck[:, None, None] * Ok
    return A


def dexp_apply(screws: np.ndarray, theta: np.ndarray, dS: np.ndarray) -> np.ndarray:
    """A(S_i, theta_i) dS_i of every joint at once (eq. 2.3.26; :func:`dexp_A` vectorised over joints).

    A dS = theta dS + sum_k c_k(theta) Omega^k dS, Omega = ad(S): the four products Omega^k dS are
    formed once per joint, and the configurations only scale them.

    Parameters
    ----------
    screws : (n, 6) array (unit omega, or omega = 0)
    theta : (m, n) array, joint values (rad, or mm for a prismatic joint)
    dS : (n, 6, k) array, screw perturbations per joint

    Returns
    -------
    (m, n, 6, k) array
    """
    S = np.asarray(screws, dtype=float)
    th = np.asarray(theta, dtype=float)
    Om = ad(S)
    OdS = [Om @ dS]
    for _ in range(3):
        OdS.append(Om @ OdS[-1])
    nrm = np.linalg.norm(S[:, :3], axis=1)
    prism = nrm < _SMALL
    n = np.where(prism, 1.0, nrm)
    a = n * th
    small = prism | (np.abs(a) < 1e-3)  # the series (exact after two terms for a prismatic joint)
    asafe = np.where(small, 1.0, a)
    s, c = np.sin(asafe), np.cos(asafe)
    coef = (
        np.where(small, th**2 / 2, (4 - asafe * s - 4 * c) / (2 * n**2)),
        np.where(small, th**3 / 6, (4 * asafe - 5 * s + asafe * c) / (2 * n**3)),
        np.where(small, th**4 / 24, (2 - asafe * s - 2 * c) / (2 * n**4)),
        np.where(small, th**5 / 120, (2 * asafe - 3 * s + asafe * c) / (2 * n**5)),
    )
    out = th[:, :, None, None] * dS
    for ck, Ok in zip(coef, OdS):
        out = out + ck[:, :, None, None] * Ok
    return out


def poe_chain(screws: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Prefix products of the POE formula (eq. 2.2.14 without M).

    Parameters
    ----------
    screws : (n, 6) array, joint screws in the base frame at the zero configuration
    q : (m, n) array, joint values

    Returns
    -------
    (m, n + 1, 4, 4) array; entry k is e^[S1]q1 ... e^[Sk]qk (entry 0 is the identity)
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m, n = q.shape
    E = exp6(screws[None, :, :] * q[:, :, None])  # (m, n, 4, 4)
    out = np.empty((m, n + 1, 4, 4))
    out[:, 0] = np.eye(4)
    for k in range(n):  # a loop over joints (n <= 7), vectorised over configurations
        out[:, k + 1] = out[:, k] @ E[:, k]
    return out


def fk(screws: np.ndarray, M: np.ndarray, q: np.ndarray) -> np.ndarray:
    """POE forward kinematics T(q) = e^[S1]q1 ... e^[Sn]qn M (eq. 2.2.14).

    Parameters
    ----------
    screws : (n, 6) array
    M : (4, 4) array, end-effector frame at the zero configuration
    q : (m, n) array

    Returns
    -------
    (m, 4, 4) array
    """
    return poe_chain(screws, q)[:, -1] @ M


def space_jacobian(screws: np.ndarray, chain: np.ndarray) -> np.ndarray:
    """Space Jacobian with respect to the joint values: column i = Ad(e^[S1]q1...e^[S(i-1)]q(i-1)) S_i.

    The d(theta) columns of the error model J_i (eq. 2.3.28); Modern Robotics eq. 5.11.

    Parameters
    ----------
    screws : (n, 6) array
    chain : (m, n + 1, 4, 4) array from :func:`poe_chain`

    Returns
    -------
    (m, 6, n) array
    """
    return np.einsum("mnij,nj->min", adjoint(chain[:, :-1]), screws)
