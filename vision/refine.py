"""Stage 4 of spot detection: the precise sub-pixel centre of an accepted spot, and its sigma.

An elliptical profile is fitted in linear light to the spot and its flanks; clipped pixels only
bound the profile from below, so the centre of a clipped spot comes from the plateau's edge and the
unclipped flanks (see :func:`_fit_profile`). In a 4:2:0 JPEG an unclipped spot is fitted in the luma
plus a fifth of the chroma difference Cr (see :data:`CHROMA_WEIGHT`). Its sigma is the fit's gain
through the pixels' error covariance, whose sizes come from the odd part of the residuals with the
fit's own share taken out (see :func:`_centre_sigma`).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import sparse
from scipy.optimize import least_squares

from lasercal.vision.errors import VisionError
from lasercal.vision.features import CR, LUMA, _robust_sigma

# An unclipped spot in a 4:2:0 JPEG is fitted in the luma plus this much of Cr. After colour
# correction a dim red spot leaves about a quarter of its red rise in the luma, twice as much in
# Cr; but Cr is stored at half resolution and quantised ~3x coarser, so its own centre is ~2x
# worse. Their JPEG errors are independent: measured on the phone renderer (JPEG quality 85-92,
# spots 0.3-0.5x clipping, speckle 0-0.2), 0.2 cuts the RMS error of red spots by ~15 % and of
# green ones by ~7 % (0.1-0.3 are within 3 % of it; 0 is the luma alone, 1.4 the red channel).
CHROMA_WEIGHT = 0.2


FIT_STRAY = 1.0  # px


def _weighted_centroid(
    sig: np.ndarray, start: tuple[float, float], radius: float, exclude: np.ndarray, iterations: int = 30
) -> tuple[float, float, np.ndarray]:
    """Intensity-weighted centroid in a circular window re-centred until it settles.

    Parameters
    ----------
    sig : (h, w) array, background-subtracted laser signal, DN
    start : (u, v), first window centre, px in ``sig``
    radius : float, window radius, px
    exclude : (h, w) bool array, pixels of other spots

    Returns
    -------
    u, v : float, px in ``sig``; weights : (h, w) array used in the last step
    """
    h, w = sig.shape
    Y, X = np.mgrid[:h, :w].astype(np.float32)
    pos = np.clip(sig, 0, None) * ~exclude
    u, v = start
    for _ in range(iterations):
        # Soft edge: a pixel straddling the circle counts by the fraction inside, so the
        # centroid moves smoothly with the window instead of in pixel steps.
        wgt = pos * np.clip(radius + 0.5 - np.hypot(X - u, Y - v), 0, 1)
        total = wgt.sum()
        if total <= 0:
            raise VisionError("empty centroid window")
        nu, nv = (wgt * X).sum() / total, (wgt * Y).sum() / total
        done = abs(nu - u) + abs(nv - v) < 1e-4
        u, v = float(nu), float(nv)
        if done:
            break
    return u, v, wgt


def _fit_profile(
    d: np.ndarray,
    valid: np.ndarray,
    clipped: np.ndarray,
    ceiling: np.ndarray,
    start: tuple[float, float],
    r_eq: float,
    noise: float,
) -> tuple[float, float, float, float] | None:
    """Elliptical spot profile fitted in linear intensity; clipped pixels only bound it from below.

    A clipped pixel says only that the light there reached the clipping level, so it adds a
    residual only where the model falls short of that level (a censored fit): the centre
    comes from where the plateau ends and from the unclipped flanks, not from the flat top.
    With clipped pixels the profile is ``A exp(-q**b / 2)`` (``b`` free: blooming and the
    tone curve flatten the flanks), else a Gaussian (``b = 1``); plus a constant offset.

    Parameters
    ----------
    d : (h, w) array, signal over the paper background, DN (linear light; for an unclipped spot
        in a 4:2:0 JPEG the encoded luma + chroma plane of :func:`_laser_plane`)
    valid : (h, w) bool array, pixels to fit (in the window, off ink and other spots)
    clipped : (h, w) bool array, pixels at the clipping level
    ceiling : (h, w) array, the clipping level over the background, linear DN
    start : (u, v), first guess of the centre, px
    r_eq : float, radius of the spot's blob, px
    noise : float, the background's noise in ``d``, linear DN (a floor of the fit's error model)

    Returns
    -------
    (u, v, sigma_u, sigma_v) px, or None when too few pixels are left or the fit wanders off.
    The sigmas propagate the residuals' asymmetry about the centre through the fit (see
    :func:`_centre_sigma`).
    """
    yy, xx = np.nonzero(valid)
    if len(xx) < 12:
        return None
    cl = clipped[yy, xx]
    data = np.where(cl, ceiling[yy, xx], d[yy, xx])
    flat = bool(cl.any())

    def model(p):
        dx, dy = xx - p[0], yy - p[1]
        sx, sy = np.exp(np.clip(p[3:5], -30, 30))  # inverse widths; clipped: a stray step must not overflow
        q = (sx * dx) ** 2 + (p[5] * dx + sy * dy) ** 2
        if flat:
            q = q ** np.exp(np.clip(p[7], -1.2, 1.1))  # the flanks' shape, exponent 0.3..3
        return p[6] + p[2] * np.exp(-0.5 * q)

    def resid(p, weight=1.0):
        r = model(p) - data
        return np.where(cl, np.minimum(r, 0), r) * weight

    s0 = -np.log(max(r_eq / (2.5 if flat else 2.0), 0.7))
    amp = max(data.max(), 1.0) * (2.0 if flat else 1.0)
    p0 = np.array([start[0], start[1], amp, s0, s0, 0.0, 0.0, 0.0])
    res = least_squares(resid, p0 if flat else p0[:7], method="lm", x_scale="jac", max_nfev=400)
    # Speckle makes the error grow with the light (multiplicative), noise does not: model the
    # residuals' variance as a + b m**2 and fit again with those weights (the likelihood's fit).
    # (Weights fixed from the first fit: weights that follow the model would bias it upwards.)
    used = np.abs(res.jac).sum(1) > 0  # censored pixels above the clipping level carry no information
    m = np.maximum(model(res.x), 0)
    A = np.column_stack([np.ones(used.sum()), m[used] ** 2])
    var = np.maximum(np.linalg.lstsq(A, res.fun[used] ** 2, rcond=None)[0], 0)
    sd = np.sqrt(max(var[0], noise**2, 1e-9) + var[1] * m * m)
    res = least_squares(resid, res.x, method="lm", x_scale="jac", max_nfev=400, kwargs={"weight": 1 / sd})
    if not res.success or np.hypot(res.x[0] - start[0], res.x[1] - start[1]) > r_eq + 2:
        return None
    u, v = float(res.x[0]), float(res.x[1])
    # The error of the centre comes from what is asymmetric about it: the odd part of the errors
    # under point reflection through the centre (noise, JPEG, speckle, the uneven bloom of a
    # speckled core, a ragged plateau edge), propagated through the fit (see _centre_sigma).
    su, sv = _centre_sigma(res, xx, yy, valid.shape, u, v, sd, model(res.x) - res.x[6])
    return u, v, float(su), float(sv)


# The noise of a pixel, in the fit's linear DN, is taken as the sum of (see _centre_sigma):
# additive noise (read noise, rounding, JPEG) of variance a + c m (m the spot's light there: shot
# noise), and multiplicative noise (speckle, the bloom of a speckled core) of variance b m**2; both
# correlated between neighbouring pixels (speckle grains, demosaicing, JPEG blocks), with a covariance
# each for the four pixels beside a pixel and the four diagonal ones (NOISE_LAGS). The multiplicative
# noise's correlation 2 and sqrt 5 px away (FAR_LAGS) follows from its correlation at 1 px as a
# Gaussian's; estimated freely from one spot, those two lags made the stated sigma's spread over the fake
# camera's photos 0.36 of itself instead of 0.24 (z RMS 1.40 against 1.17), and without them the phone
# renderer's clipped speckled spots were under-reported 1.53x.
NOISE_LAGS = (((1, 0), (0, 1)), ((1, 1), (-1, 1)))
FAR_LAGS = {4: ((2, 0), (0, 2)), 5: ((2, 1), (1, 2), (-2, 1), (-1, 2))}


def _centre_sigma(
    res, xx: np.ndarray, yy: np.ndarray, shape: tuple, u: float, v: float, sd: np.ndarray, light: np.ndarray
):
    """1-sigma error of a fitted centre: the fit's gain through the covariance of the pixels' errors,
    that covariance estimated from the fit's residuals with the fit's own share taken out.

    The fitted parameters move by ``-G e`` for weighted pixel errors ``e`` (``G = (J^T J)^-1 J^T``, J the
    weighted Jacobian), so the centre's covariance is (eq. C1)

        Cov(u, v) = G Sigma G^T,   Sigma = sum_l theta_l S_l,

    with Sigma the weighted errors' covariance, a sum of known shapes S_l times unknown sizes theta_l:
    additive noise (``D^2``, ``D^2 diag(m)``: constant and shot), multiplicative noise (``D M E_k M D``)
    and correlated additive noise (``D E_k D``), D = diag(1 / sd) the fit's weights, M = diag(m) the
    spot's light, E_k the pairs of neighbouring pixels of a lag group (:data:`NOISE_LAGS`; E_0 = I),
    and the multiplicative noise at :data:`FAR_LAGS`, sized from its correlation at 1 px.

    The sizes are fitted by moments of the residuals r. Only the part of the errors that is odd under
    point reflection through (u, v) moves the centre, and a symmetric misfit of the profile (a spot not
    quite a Gaussian, a tone curve assumed wrong) is even: the moments are taken of the odd part
    ``o = O r`` (O: a residual minus the bilinear sample of the residuals at its mirror pixel, where all
    four of its pixels were fitted). The residuals are not the errors: the fit has absorbed their part
    along its own Jacobian (for a spot a few speckle grains wide, a large part), ``r = K e`` with
    ``K = I - Q Q^T`` (Q an orthonormal basis of J's columns). So the sizes solve the moment equations
    of restricted maximum likelihood (eq. C2): for each shape, with ``T_k = O^T S_k O``,

        E[o^T S_k o] = sum_l theta_l tr(T_k K S_l K),

        tr(T K S K) = tr(T S) - 2 tr(Q^T S T Q) + tr(Q^T T Q Q^T S Q),

    a linear system for theta. Taking the residuals' moments for the errors' (leaving K out) under-reports
    a speckled spot ~1.5x in the fake camera's photos. Censored pixels (clipped, the model above the
    clipping level: no Jacobian) are left out. Where the noisy theta make the variance fall below half
    what the lag-0 terms alone give, that half is kept.

    Parameters
    ----------
    res : scipy OptimizeResult of the weighted fit; ``res.fun`` weighted residuals, ``res.jac``
        their Jacobian, (u, v) its first two parameters
    xx, yy : (n,) int arrays, the fitted pixels; shape : (h, w) of the box
    u, v : float, the fitted centre, px
    sd : (n,) array, the fit's error model per pixel (its weights are 1 / sd), linear DN
    light : (n,) array, the fitted spot's light per pixel over its background, linear DN

    Returns
    -------
    (sigma_u, sigma_v), px
    """
    used = np.nonzero(np.abs(res.jac).sum(1) > 0)[0]
    n = len(used)
    J, r = res.jac[used], res.fun[used]
    d, m = 1 / sd[used], np.maximum(light[used], 0)
    gain = (np.linalg.pinv(J.T @ J) @ J.T)[:2]  # d(u, v) / d(weighted data)
    Q = np.linalg.qr(J)[0]
    px, py = xx[used], yy[used]
    grid = np.full(shape, -1)  # index of the fitted pixel at (y, x), -1 where none
    grid[py, px] = np.arange(n)
    h, w = shape
    D = sparse.diags(d)
    shapes = [D @ D, D @ sparse.diags(m) @ D, sparse.diags((d * m) ** 2)]

    def pairs(group):
        ij = []
        for dx, dy in group:
            a = grid[max(0, -dy) : h - max(0, dy), max(0, -dx) : w - max(0, dx)]
            b = grid[max(0, dy) : h - max(0, -dy), max(0, dx) : w - max(0, -dx)]
            ok = (a >= 0) & (b >= 0)
            ij.append((a[ok], b[ok]))
        i, j = np.concatenate([q[0] for q in ij]), np.concatenate([q[1] for q in ij])
        E = sparse.coo_matrix((np.ones(len(i)), (i, j)), (n, n)).tocsr()
        return E + E.T

    DM = D @ sparse.diags(m)
    for group in NOISE_LAGS:
        E = pairs(group)
        shapes += [DM @ E @ DM, D @ E @ D]
    # The odd part under point reflection through the centre: a pixel's residual minus the bilinear
    # sample of the residuals at its mirror image, where all four of that sample's pixels were fitted.
    mx, my = 2 * u - px, 2 * v - py
    x0, y0 = np.floor(mx).astype(int), np.floor(my).astype(int)
    fx, fy = mx - x0, my - y0
    rows, cols, vals, whole = [], [], [], np.ones(n, bool)
    for ox, oy, wgt in (
        (0, 0, (1 - fx) * (1 - fy)),
        (1, 0, fx * (1 - fy)),
        (0, 1, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        cx, cy = x0 + ox, y0 + oy
        inside = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
        k = np.where(inside, grid[np.clip(cy, 0, h - 1), np.clip(cx, 0, w - 1)], -1)
        whole &= (k >= 0) | (wgt == 0)
        rows.append(np.arange(n)), cols.append(np.maximum(k, 0)), vals.append(np.where(k >= 0, wgt, 0))
    mirror = sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), (n, n))
    odd = sparse.diags(whole.astype(float)) @ (sparse.identity(n) - mirror.tocsr())
    # E[o^T S_k o] = sum_l theta_l tr(T_k K S_l K), T_k = O^T S_k O, o = O r (eq. C2 with the odd part)
    T = [(odd.T @ S @ odd).tocsr() for S in shapes]
    SQ = [S @ Q for S in shapes]
    TQ = [t @ Q for t in T]
    QSQ, QTQ = [Q.T @ x for x in SQ], [Q.T @ x for x in TQ]
    k = len(shapes)
    A = np.empty((k, k))
    for p in range(k):
        for q in range(k):
            A[p, q] = (
                T[p].multiply(shapes[q]).sum()
                - 2 * float((TQ[p] * SQ[q]).sum())
                + float((QTQ[p] * QSQ[q].T).sum())
            )
    o = odd @ r
    moments = np.array([o @ (S @ o) for S in shapes])
    theta = np.linalg.lstsq(A, moments, rcond=None)[0]
    # eq. C1, per axis
    # Farther lags of the multiplicative noise (FAR_LAGS), from its correlation at 1 px as a Gaussian's:
    # rho(d) = rho(1)**(d**2) (speckle grains and bloom are smooth blobs).
    rho = float(np.clip(theta[3] / theta[2], 0.0, 0.9)) if theta[2] > 0 else 0.0
    far = [(theta[2] * rho**d2, DM @ pairs(group) @ DM) for d2, group in FAR_LAGS.items()]
    var = np.array([sum(t * float(g @ (S @ g)) for t, S in [*zip(theta, shapes), *far]) for g in gain])
    floor = np.array([sum(t * float(g @ (S @ g)) for t, S in zip(theta[:3], shapes[:3])) for g in gain])
    # A noisy estimate can come out below what the pixels' own variance says: half that is the floor.
    su, sv = np.sqrt(np.maximum(var, 0.5 * np.maximum(floor, 0)) + 1e-18)
    return float(su), float(sv)


def _centroid_sigma(sig: np.ndarray, wgt: np.ndarray, u: float, v: float) -> tuple[float, float]:
    """1-sigma error of a weighted centroid, from the spot's own asymmetry.

    Noise and speckle make the spot asymmetric about its centre; the part of the
    signal that is odd under point reflection through (u, v) has twice the
    per-pixel variance of the errors, which propagate through the centroid's
    lever arms (a sandwich estimate), inflated for the correlation of neighbours.
    """
    h, w = sig.shape
    Y, X = np.mgrid[:h, :w].astype(np.float32)
    mirror = cv2.remap(
        sig.astype(np.float32), (2 * u - X), (2 * v - Y), cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    inside = wgt > 0
    odd = np.where(inside, sig - mirror, 0)
    odd2 = odd[inside] ** 2 / 2
    # Speckle grains span several pixels: inflate by the neighbours' correlation.
    rho = np.clip(
        ((odd[:, 1:] * odd[:, :-1]).sum() + (odd[1:] * odd[:-1]).sum()) / (2 * (odd**2).sum() + 1e-12),
        0,
        0.95,
    )
    total = wgt.sum() / (1 + 2 * rho)
    su = np.sqrt(((X[inside] - u) ** 2 * odd2).sum()) / total
    sv = np.sqrt(((Y[inside] - v) ** 2 * odd2).sum()) / total
    return float(su), float(sv)


def _laser_plane(ch: int) -> np.ndarray:
    """BGR weights of the plane an unclipped spot is fitted in, for a 4:2:0 JPEG: the luma plus
    :data:`CHROMA_WEIGHT` times the chroma difference (Cr) signed so that the laser raises it."""
    return (LUMA + CHROMA_WEIGHT * (1 if ch == 2 else -1) * CR).astype(np.float32)


def _border_noise(x: np.ndarray) -> float:
    """Robust sigma of a plane over its box's 2-px border (the background there), at least 0.3 DN."""
    border = np.concatenate([x[:2].ravel(), x[-2:].ravel(), x[2:-2, :2].ravel(), x[2:-2, -2:].ravel()])
    return max(_robust_sigma(border - np.median(border)), 0.3)
