"""Stage 4 of spot detection: the precise sub-pixel centre of an accepted spot, and its sigma.

An elliptical profile is fitted in linear light to the spot and its flanks; clipped pixels only
bound the profile from below, so the centre of a clipped spot comes from the plateau's edge and the
unclipped flanks (see :func:`_fit_profile`). In a 4:2:0 JPEG an unclipped spot is fitted in the luma
plus a fifth of the chroma difference Cr (see :data:`CHROMA_WEIGHT`). Its sigma propagates the
asymmetry of the fit's residuals about the centre through the fit (see :func:`_centre_sigma`).
"""

from __future__ import annotations

import cv2
import numpy as np
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
    su, sv = _centre_sigma(res, xx, yy, valid.shape, u, v)
    return u, v, float(su), float(sv)


# The reported sigma is the geometric mean of two sandwich estimates of the centre's variance with
# opposite biases (see _centre_sigma); the lagged one is scaled by LAG_SCALE, set on the phone
# renderer over 0.3-30x clipping, both colours and speckle 0-0.2 (120 photos a cell: the
# correlation-sum estimate alone gave an actual spread of 0.68-1.27 of it, the lagged one alone,
# unscaled, 1.04-1.58). Checked on three other sets of 80 photos a cell: 0.71-1.31 in every cell.
LAG_SCALE = 1.3


def _centre_sigma(
    res, xx: np.ndarray, yy: np.ndarray, shape: tuple, u: float, v: float
) -> tuple[float, float]:
    """1-sigma error of a fitted centre, from the asymmetry of the fit's residuals about it.

    The model is point-symmetric about (u, v), so only the odd part of the errors moves the
    centre, and the odd part of the data is the odd part of the residuals. A residual minus its
    mirror image (bilinear, so divided by sqrt(1 + the interpolation weights' squares)) stands for
    a pixel's error; mirroring the residuals rather than the data keeps the interpolation error
    of a steep profile (a clipped plateau's edge) out, which the data's own mirror counted as error.
    The errors are propagated through the fit's influence on (u, v) (its gain) in two ways, whose
    geometric mean is returned:

    - correlation sum: the sum of gain**2 err**2, times the sum of the error field's
      autocorrelation out to 3 px (speckle grains and demosaicing make neighbours alike). The
      field is smoothed by [1 2 1] first: Bayer demosaicing leaves a pixel-scale zipper on a
      spot's edges that is odd about the centre but averages out in the fit. Each pixel's square
      is divided by 1 - kappa * leverage (capped): the fitted centre has already absorbed part of
      the odd error it is estimated from. Its correlation comes from the whole field, so where
      flank noise outweighs the speckle on the core it is diluted: it over-reports clean clipped
      spots (up to ~1.5x) and under-reports speckled ones.
    - lagged pairs: the sum of gain_i gain_j err_i err_j over pixel pairs up to 2 px apart
      (a truncated heteroscedasticity-and-autocorrelation sandwich), leaving out each pixel's
      pairs near its own mirror image (anti-correlated by construction). Each pair is weighted
      by its own gains, so the speckle on the core counts where it acts, and an alternating
      zipper cancels as it does in the fit. But the residuals are orthogonal to the gain, which
      eats part of the sum: it under-reports, by a factor that varies less (scaled by LAG_SCALE).

    Parameters
    ----------
    res : scipy OptimizeResult of the weighted fit; ``res.fun`` weighted residuals, ``res.jac``
        their Jacobian, (u, v) its first two parameters
    xx, yy : (n,) int arrays, the fitted pixels; shape : (h, w) of the box
    u, v : the fitted centre, px

    Returns
    -------
    (sigma_u, sigma_v), px
    """
    J = res.jac
    cov = np.linalg.pinv(J.T @ J)
    gain = (cov @ J.T)[:2]  # d(u, v) / d(weighted data)
    R = np.zeros(shape, np.float32)
    M = np.zeros(shape, np.float32)
    R[yy, xx], M[yy, xx] = res.fun, 1
    mx, my = (2 * u - xx).astype(np.float32), (2 * v - yy).astype(np.float32)
    mirror = _remap_points(R, mx, my)
    whole = _remap_points(M, mx, my) > 0.999
    fx, fy = mx - np.floor(mx), my - np.floor(my)
    w2 = ((1 - fx) ** 2 + fx**2) * ((1 - fy) ** 2 + fy**2)
    err = np.where(whole, (res.fun - mirror) / np.sqrt(1 + w2), 0)
    # Correlation sum.
    field = np.zeros(shape)
    field[yy, xx] = err
    k121 = np.array([0.25, 0.5, 0.25])
    field = cv2.sepFilter2D(field, -1, k121, k121, borderType=cv2.BORDER_CONSTANT)
    kappa = _correlation_sum(field, 3)
    lever = np.einsum("ij,jk,ik->i", J[:, :2], cov[:2, :2], J[:, :2])  # each pixel's pull on (u, v)
    var_sum = kappa * (gain**2 @ (field[yy, xx] ** 2 / (1 - np.minimum(kappa * lever, 0.5))))
    # Lagged pairs.
    P = np.zeros((2, *shape))
    P[:, yy, xx] = gain * err
    h, w = shape
    Y, X = np.mgrid[:h, :w]
    lag0 = (P * P).sum((1, 2))
    var_lag = lag0.copy()
    r = 2
    for dy in range(0, r + 1):  # each unordered pair once, counted twice
        for dx in range(-r, r + 1):
            if dy == 0 and dx <= 0:
                continue
            a = (slice(0, h - dy), slice(max(0, -dx), w - max(0, dx)))
            b = (slice(dy, h), slice(max(0, dx), w - max(0, -dx)))
            own_mirror = (np.abs(2 * X[a] + dx - 2 * u) <= r) & (np.abs(2 * Y[a] + dy - 2 * v) <= r)
            var_lag += 2 * np.where(own_mirror, 0, P[(slice(None), *a)] * P[(slice(None), *b)]).sum((1, 2))
    var_lag = LAG_SCALE**2 * np.maximum(var_lag, 0.25 * lag0)
    su, sv = (var_sum * var_lag) ** 0.25
    return float(su), float(sv)


REMAP_ROW = 32_000  # cv2.remap refuses maps (and images) of 32,767 px or more on a side


def _remap_points(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``img`` at points (x, y), px, 0 outside (``cv2.remap`` with
    ``BORDER_CONSTANT``), for any number of points: the point list is folded into rows short
    enough for remap (a large spot's window has more than 32,767 pixels).

    Parameters
    ----------
    img : (h, w) float32 array, h and w < 32,767; x, y : (n,) float32 arrays, px

    Returns
    -------
    (n,) float32 array
    """
    n = len(x)
    rows = -(-n // REMAP_ROW)
    pad = rows * REMAP_ROW - n
    mx = np.pad(x, (0, pad), constant_values=-1).reshape(rows, -1)
    my = np.pad(y, (0, pad), constant_values=-1).reshape(rows, -1)
    return cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT).ravel()[:n]


def _correlation_sum(res: np.ndarray, reach: int) -> float:
    """How many pixels one independent error spans: the sum of the errors' autocorrelation.

    Demosaicing, JPEG blocks and speckle grains make neighbouring errors alike; the variance
    of a fitted centre grows by the sum of their normalised autocorrelation over lags up to
    ``reach`` px (a stationary-noise sandwich estimate).

    Parameters
    ----------
    res : (h, w) array, errors, 0 outside the fitted pixels
    reach : int, largest lag, px

    Returns
    -------
    float >= 1
    """
    ys, xs = np.nonzero(res)
    if len(ys) == 0:
        return 1.0
    res = res[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    h, w = res.shape
    r0 = float((res * res).sum())
    f = np.fft.rfft2(res, (2 * h, 2 * w))  # zero-padded: no wrap-around
    ac = np.fft.irfft2(f * np.conj(f), (2 * h, 2 * w))
    dy, dx = np.fft.fftfreq(2 * h, 1 / (2 * h)), np.fft.fftfreq(2 * w, 1 / (2 * w))  # signed lags, px
    near = (np.abs(dy)[:, None] <= reach) & (np.abs(dx)[None, :] <= reach)
    return max(float(ac[near].sum()) / r0, 1.0)


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
