"""Laser-spot detection and the precise sub-pixel centroid.

Coordinates are pixels in OpenCV's convention (pixel centres at integer
coordinates, ``u`` to the right, ``v`` down); intensities are digital numbers (DN)
of the photo. ImageJ reports the same point at ``(u + 0.5, v + 0.5)``.

Detection, on a red (or green) laser on white paper under room light:

1. candidates: on a 1/f-size block average (fast on 12-megapixel photos), the
   paper level (a tile percentile, so black markers do not sink it) is removed
   from the laser's channel and from its *colour excess* (the channel minus the
   brighter other one: ~0 on white paper, black ink and white glare alike). Laser
   light is both brighter than the paper and coloured; both must pass 6 robust
   sigmas. A saturated white core keeps a coloured rim, so it is found too.
2. each candidate, at full resolution: a plane fitted to the box border is the
   local background. Rejected: blobs not clearly brighter than the paper (red ink,
   JPEG colour fringes beside ink), not laser-coloured on their unsaturated pixels
   (white reflections), or dark at their own centre (fringe rings).
3. centroid (``precise``): background-subtracted intensity-weighted centroid of the
   laser's channel in a circular window re-centred until it settles, excluding
   other spots' pixels. Clipping a symmetric spot keeps it symmetric, so
   saturated pixels take part at their clipped value and do not bias the centre.
   Where printed ink lies under an unsaturated spot, a Gaussian is fitted (in
   linear intensity) to the pixels off the ink instead; spots on ink are flagged.

With a laser-off reference photo the candidates come from the difference image,
which holds nothing but laser light, and fainter spots are believed.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from lasercal.vision.errors import NoSpotError, SpotCountError, VisionError
from lasercal.vision.imagej import measure as imagej_measure
from lasercal.vision.images import full_scale
from lasercal.vision.spot import CHANNEL, Spot

LUMA = np.array([0.114, 0.587, 0.299])  # BGR weights of JPEG's luma (ITU-R BT.601)
MAX_CANDIDATES = 50


@dataclass(frozen=True)
class Candidate:
    """A region that may hold a laser spot.

    Attributes
    ----------
    box : (x0, y0, x1, y1) ints, px, half-open, full resolution
    u, v : float, rough centre, px
    """

    box: tuple[int, int, int, int]
    u: float
    v: float


@dataclass(frozen=True)
class Rejection:
    """Why a candidate is not a laser spot (``kind`` is ``"dim"`` or ``"white"``)."""

    kind: str
    u: float
    v: float


def _channels(img: np.ndarray, ch: int) -> tuple[np.ndarray, np.ndarray]:
    """The laser's channel and its colour excess (the channel minus the brighter
    other one, clipped at 0); a grey image is both."""
    if img.ndim == 2:
        return img, img
    laser, a, b = (cv2.extractChannel(img, c) for c in (ch, *(c for c in range(3) if c != ch)))
    return laser, cv2.subtract(laser, cv2.max(a, b))


def _robust_sigma(x: np.ndarray) -> float:
    x = x.ravel()[:: max(1, x.size // 50_000)]  # a sample is plenty for a noise level
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


def _highpass(small: np.ndarray, tile: int = 24) -> np.ndarray:
    """Subtract the paper level (room light, tint, vignetting) from a small image.

    The paper level is the 90th percentile of tiles, median-filtered and
    interpolated: a spot covers too little of a tile to lift it, and a black marker
    too little to sink it, so the white cells inside a marker are not "brighter
    than their surroundings" as they would be against a local median.
    """
    h, w = small.shape
    if min(h, w) < 4:
        return small - np.median(small)
    ty, tx = max(h // tile, 1), max(w // tile, 1)
    th, tw = (h // ty) // 2, (w // tx) // 2
    sub = small[: ty * th * 2 : 2, : tx * tw * 2 : 2]  # every other pixel: plenty for a percentile
    tiles = sub.reshape(ty, th, tx, tw).transpose(0, 2, 1, 3).reshape(ty, tx, -1)
    k = int(0.9 * (tiles.shape[2] - 1))
    level = np.ascontiguousarray(np.partition(tiles, k, axis=2)[..., k], np.float32)
    if min(ty, tx) >= 3:
        level = cv2.medianBlur(level, 3)
    return small - cv2.resize(level, (w, h), interpolation=cv2.INTER_LINEAR)


def find_candidates(
    img: np.ndarray, colour: str = "red", reference: np.ndarray | None = None, k_sigma: float = 6.0
) -> list[Candidate]:
    """Regions of laser-coloured light brighter than their surroundings.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16
    colour : "red" or "green"
    reference : array like ``img`` or None, the same view with the laser off
    k_sigma : float, threshold in robust sigmas of the background

    Returns
    -------
    list of Candidate, strongest first, at most 50
    """
    h, w = img.shape[:2]
    ch = CHANNEL[colour]
    src = cv2.subtract(img, reference) if reference is not None else img
    f = max(1, min(h, w) // 750)  # block size: ~750 rows keep spots of sigma >= 1 px visible
    floor = 0.03 * full_scale(img)  # JPEG flattens paper to a noise-free level: keep a floor
    # Block-average first: the colour excess of block means is close enough for finding
    # spots, and it spares full-resolution passes over 12-megapixel photos.
    small = cv2.resize(src, (w // f, h // f), interpolation=cv2.INTER_AREA) if f > 1 else src
    laser, excess = _channels(small, ch)
    strength = _highpass(excess.astype(np.float32))
    mask = strength > max(k_sigma * _robust_sigma(strength), floor)
    if src.ndim == 3:
        # Laser light is both coloured and brighter than its surroundings; JPEG colour
        # fringes at ink edges are coloured but not brighter, red ink neither.
        bright = _highpass(laser.astype(np.float32))
        mask &= bright > max(k_sigma * _robust_sigma(bright), floor)
    # Speckle and JPEG blocks break a spot's mask into pieces: join pieces a few pixels apart.
    mask = cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8))
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return []
    on = labels > 0  # few pixels: a scatter-max over them is cheap
    best = np.full(n, -np.inf)
    np.maximum.at(best, labels[on], strength[on])
    order = np.argsort(-best[1:])[:MAX_CANDIDATES] + 1
    out = []
    for i in order:
        x, y, bw, bh = stats[i, :4]
        margin = max(4, bw, bh)
        box = (
            max((x - margin) * f, 0),
            max((y - margin) * f, 0),
            min((x + bw + margin) * f, w),
            min((y + bh + margin) * f, h),
        )
        out.append(
            Candidate(
                tuple(int(b) for b in box),
                float(cents[i, 0] * f + (f - 1) / 2),
                float(cents[i, 1] * f + (f - 1) / 2),
            )
        )
    return out


def _plane_background(roi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fit a plane to each channel on the box border (2 px frame), robustly.

    Parameters
    ----------
    roi : (h, w, c) float32 array

    Returns
    -------
    background : (h, w, c) array, DN; noise : (c,) array, robust sigma of the border, DN
    """
    h, w, c = roi.shape
    border = np.zeros((h, w), bool)
    border[:2], border[-2:], border[:, :2], border[:, -2:] = True, True, True, True
    yy, xx = np.nonzero(border)
    A = np.column_stack([np.ones(len(xx)), xx - w / 2, yy - h / 2])
    vals = roi[yy, xx].reshape(len(xx), c).astype(float)
    coef, *_ = np.linalg.lstsq(A, vals, rcond=None)
    res = vals - A @ coef
    mad = 1.4826 * np.median(np.abs(res), 0) + 1e-6
    keep = np.all(np.abs(res) < 3 * mad + 1, 1)  # drop border pixels crossed by ink or a neighbour spot
    if keep.sum() >= 8:
        coef, *_ = np.linalg.lstsq(A[keep], vals[keep], rcond=None)
        res = vals[keep] - A[keep] @ coef
    noise = np.maximum(np.std(res, 0), 0.3)  # quantisation keeps at least ~0.3 DN
    Y, X = np.mgrid[:h, :w]
    bg = coef[0] + (X - w / 2)[..., None] * coef[1] + (Y - h / 2)[..., None] * coef[2]
    return bg.astype(np.float32), noise


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


def _ink(roi: np.ndarray, bg: np.ndarray, ch: int) -> np.ndarray | None:
    """Printed pixels in the box, or None when there are none.

    The laser only adds light to the other two channels (cross-talk), so a pixel much
    darker than the paper in both of them is ink. Grown by 2 px: the lens blurs ink
    edges into their neighbours.
    """
    others = np.delete(roi, ch, axis=2) / np.maximum(np.delete(bg, ch, axis=2), 1)
    ink = others.max(axis=2) < 0.6
    if not ink.any():
        return None
    return cv2.dilate(ink.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)


def _fit_gaussian(
    raw: np.ndarray,
    bg: np.ndarray,
    valid: np.ndarray,
    start: tuple[float, float],
    r_eq: float,
    full: float,
    gamma: float,
) -> tuple[float, float, float, float] | None:
    """Elliptical Gaussian fitted in linear intensity to the ``valid`` pixels.

    Parameters
    ----------
    raw : (h, w) array, the laser's channel as recorded, DN
    bg : (h, w) array, its paper background, DN
    valid : (h, w) bool array, pixels to fit (not ink, not clipped)
    start : (u, v), first guess of the centre, px
    r_eq : float, radius of the spot's blob, px
    full : float, full scale, DN
    gamma : float, encoding gamma of the photo

    Returns
    -------
    (u, v, sigma_u, sigma_v) px, or None when too few pixels are left to fit
    """
    yy, xx = np.nonzero(valid)
    if len(xx) < 12:
        return None
    d = full * (np.clip(raw[yy, xx] / full, 0, None) ** gamma - np.clip(bg[yy, xx] / full, 0, None) ** gamma)

    def resid(p):
        dx, dy = xx - p[0], yy - p[1]
        l11, l22 = np.exp(p[3]), np.exp(p[4])
        return p[2] * np.exp(-0.5 * ((l11 * dx) ** 2 + (p[5] * dx + l22 * dy) ** 2)) - d

    s0 = -np.log(max(r_eq / 2, 0.7))
    p0 = np.array([start[0], start[1], max(d.max(), 1.0) * 2, s0, s0, 0.0])
    res = least_squares(resid, p0, loss="soft_l1", f_scale=max(np.std(d) / 4, 1.0), x_scale="jac")
    if not res.success or np.hypot(res.x[0] - start[0], res.x[1] - start[1]) > 2 * r_eq + 2:
        return None
    dof = max(len(d) - 6, 1)
    cov = np.linalg.pinv(res.jac.T @ res.jac) * (res.fun @ res.fun / dof)
    return float(res.x[0]), float(res.x[1]), float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))


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


def measure_spot(
    img: np.ndarray,
    cand: Candidate,
    colour: str = "red",
    reference: np.ndarray | None = None,
    others: list[Candidate] = (),
    gamma: float = 2.2,
    luma: bool = False,
) -> Spot | Rejection:
    """Measure one candidate with the precise method.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array
    cand : Candidate
    colour : "red" or "green"
    reference : laser-off photo like ``img``, or None
    others : the other candidates, whose pixels are kept out of the window
    gamma : float, the photo's encoding gamma (for the fit when ink lies under the spot)
    luma : bool, centroid on the luma instead of the laser's channel: a JPEG with
        chroma subsampling keeps only the luma at full resolution

    Returns
    -------
    Spot, or Rejection when the candidate is not laser light.
    """
    h, w = img.shape[:2]
    ch = CHANNEL[colour] if img.ndim == 3 else 0
    full = full_scale(img)
    x0, y0, x1, y1 = cand.box
    for attempt in range(4):  # grow the box until the spot no longer touches its border
        roi = img[y0:y1, x0:x1].astype(np.float32).reshape(y1 - y0, x1 - x0, -1)
        if reference is not None:
            roi = roi - reference[y0:y1, x0:x1].astype(np.float32).reshape(roi.shape)
        bg, noise = _plane_background(roi)
        delta = roi - bg
        sig = delta[..., ch]
        peak_d = float(sig.max())
        edge = max(sig[0].max(), sig[-1].max(), sig[:, 0].max(), sig[:, -1].max())
        if edge < 0.05 * peak_d or (x0, y0, x1, y1) == (0, 0, w, h) or attempt == 3:
            break
        gx, gy = (x1 - x0) // 2, (y1 - y0) // 2
        x0, y0, x1, y1 = max(x0 - gx, 0), max(y0 - gy, 0), min(x1 + gx, w), min(y1 + gy, h)
    # Not brighter than the paper: ink or a JPEG fringe, not light. A reference photo
    # removes ink and fringes, so fainter spots are believed then.
    contrast = (0.05 if reference is not None else 0.08) * full
    if peak_d < max(8 * noise[ch], contrast):
        return Rejection("dim", cand.u, cand.v)
    thr = max(4 * noise[ch], 0.15 * peak_d)
    smooth = cv2.GaussianBlur(sig, (0, 0), 1.0)  # speckle would split a spot into several blobs
    bright = (smooth > thr).astype(np.uint8)
    plain = img[y0:y1, x0:x1].astype(np.float32).reshape(roi.shape)  # the photo itself, not a difference
    plain_bg = bg if reference is None else _plane_background(plain)[0]
    ink = _ink(plain, plain_bg, ch) if img.ndim == 3 else None
    if ink is not None:
        # A printed cross under the spot cuts it into pieces: bridge them over the ink.
        bright |= (ink & cv2.dilate(bright, np.ones((7, 7), np.uint8)).astype(bool)).astype(np.uint8)
    n, labels = cv2.connectedComponents(bright, connectivity=8)
    if n <= 1:
        return Rejection("dim", cand.u, cand.v)
    iy, ix = np.unravel_index(np.argmax(np.where(labels > 0, smooth, -np.inf)), sig.shape)
    blob = labels == labels[iy, ix]
    if blob.sum() < 4:
        return Rejection("dim", cand.u, cand.v)  # a lone bright pixel: JPEG ringing or noise, not a spot
    if img.ndim == 3 and reference is None and peak_d < 0.15 * full:
        # JPEG's coarse colour planes leave a faint laser-coloured fringe beside ink: a
        # weak blob next to pixels darker than the paper in the other channels is one.
        around = cv2.dilate(blob.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool)
        if np.max(np.delete(delta, ch, axis=2), axis=2)[around].min() < -0.15 * full:
            return Rejection("dim", cand.u, cand.v)
    raw = plain[..., ch]
    clipped = raw >= 0.985 * full
    if img.ndim == 3:
        # Colour test on unsaturated pixels near the blob: a white reflection has as
        # much excess in the other channels as in the laser's.
        near = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~clipped
        near &= sig > thr / 2
        colour_ex = cv2.blur(sig - np.max(np.delete(delta, ch, axis=2), axis=2), (3, 3))
        if near.sum() >= 3 and colour_ex[near].sum() < 0.3 * sig[near].sum():
            return Rejection("white", cand.u, cand.v)
        # JPEG ringing beside black ink is faintly coloured; laser light is strongly so.
        if colour_ex[near | blob].max(initial=0) < max(6 * noise[ch], contrast / 2):
            return Rejection("white", cand.u, cand.v)
    exclude = np.zeros(sig.shape, bool)
    for o in others:
        ox, oy = int(round(o.u)) - x0, int(round(o.v)) - y0
        if 0 <= ox < sig.shape[1] and 0 <= oy < sig.shape[0] and labels[oy, ox] > 0 and not blob[oy, ox]:
            exclude |= labels == labels[oy, ox]
    r_eq = np.sqrt(blob.sum() / np.pi)
    m = cv2.moments(blob.astype(np.uint8), binaryImage=True)
    start = (m["m10"] / m["m00"], m["m01"] / m["m00"])
    cen = delta @ LUMA if luma and img.ndim == 3 else sig
    u, v, wgt = _weighted_centroid(cen, start, 1.1 * r_eq + 1, exclude)
    # A spot is brightest near its centre; a ring (JPEG fringe around ink) is dark there.
    if smooth[int(round(v)), int(round(u))] < 0.3 * smooth[blob].max() and ink is None:
        return Rejection("dim", cand.u, cand.v)
    Y, X = np.mgrid[: sig.shape[0], : sig.shape[1]]
    window = np.hypot(X - u, Y - v) <= 1.5 * r_eq + 2
    on_ink = ink is not None and bool((ink & window).any())
    saturated = bool(clipped[blob].any())
    if on_ink and not saturated:
        # Printed ink under the spot swallows laser light on one side: fit the spot's
        # shape to the pixels off the ink instead. (Clipped, blooming spots are not
        # Gaussian enough for this; they keep the centroid, and a warning.)
        fit = _fit_gaussian(raw, plain_bg[..., ch], window & ~ink & ~exclude, (u, v), r_eq, full, gamma)
        if fit is None:
            return Rejection("dim", cand.u, cand.v)
        u, v, su, sv = fit
    else:
        su, sv = _centroid_sigma(cen, wgt, u, v)
    return Spot(u + x0, v + y0, su, sv, float(raw[blob].max()), saturated, int(blob.sum()), on_ink=on_ink)


def _dedupe(spots: list[Spot]) -> list[Spot]:
    """Drop spots found twice: two candidates of one spot converge within its radius."""
    out: list[Spot] = []
    for s in sorted(spots, key=lambda s: -s.peak * s.area):
        if all(np.hypot(s.u - o.u, s.v - o.v) > max(3.0, np.sqrt(max(s.area, o.area) / np.pi)) for o in out):
            out.append(s)
    return out


def detect_spots(
    img: np.ndarray,
    name: str = "image",
    colour: str = "red",
    reference: np.ndarray | None = None,
    expect: int | None = 1,
    method: str = "precise",
    imagej_mode: str = "centroid",
    imagej_threshold: str = "default",
    imagej_box: int = 64,
    gamma: float = 2.2,
    luma: bool = False,
) -> tuple[list[Spot], list[str]]:
    """Find and measure the laser spots of one photo.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16
    name : str, the photo's name for messages
    colour : "red" or "green"
    reference : laser-off photo of the same view and size, or None
    expect : int or None, the number of spots expected; None accepts any number
    method : "precise" or "imagej"
    imagej_mode, imagej_threshold, imagej_box : see :func:`vision.imagej.measure`
    gamma : float, the photo's encoding gamma (2.2 camera JPEG, 1 linear)
    luma : bool, precise centroid on the luma (for JPEGs with subsampled chroma)

    Returns
    -------
    spots : list of Spot, sorted by v then u
    warnings : list of str

    Raises
    ------
    NoSpotError
        Nothing that looks like laser light.
    SpotCountError
        More spots than ``expect``.
    """
    if reference is not None and reference.shape != img.shape:
        raise VisionError(
            f"{name}: the reference photo is {reference.shape[1]}x{reference.shape[0]} px, "
            f"the photo {img.shape[1]}x{img.shape[0]} px"
        )
    cands = find_candidates(img, colour, reference)
    found, rejected = [], []
    for c in cands:
        r = measure_spot(img, c, colour, reference, [o for o in cands if o is not c], gamma, luma)
        (rejected if isinstance(r, Rejection) else found).append(r)
    spots = _dedupe(found)
    warnings = []
    if img.ndim == 2:
        warnings.append("grey photo: white reflections cannot be told from laser light")
    if not spots:
        why = {
            "dim": "not brighter than the paper (printed marks?)",
            "white": "white, not laser-coloured (reflections?)",
        }
        kinds = [k for k in why if any(r.kind == k for r in rejected)]
        detail = (
            "; rejected: " + ", ".join(f"{sum(r.kind == k for r in rejected)} {why[k]}" for k in kinds)
            if kinds
            else ""
        )
        raise NoSpotError(f"{name}: no {colour} laser spot found{detail}")
    if expect is not None and len(spots) > expect:
        where = ", ".join(f"({s.u:.1f}, {s.v:.1f})" for s in spots[:6])
        raise SpotCountError(
            f"{name}: {len(spots)} spots found where {expect} "
            f"{'is' if expect == 1 else 'are'} expected, at px {where}"
            f"{' ...' if len(spots) > 6 else ''} (use --expect N for photos with several spots)"
        )
    for sp in spots:
        if sp.on_ink:
            warnings.append(
                f"spot at ({sp.u:.1f}, {sp.v:.1f}) px lies on printed ink, which swallows part of its "
                "light: its centre may be off by a few tenths of a pixel (aim beside the mark)"
            )
    if expect is not None and len(spots) < expect:
        warnings.append(f"{len(spots)} spot{'s' * (len(spots) != 1)} found where {expect} are expected")
    if method == "imagej":
        measured = []
        for s in spots:
            box = _imagej_box(img.shape, s, imagej_box)
            try:
                measured.append(imagej_measure(img, box, imagej_mode, imagej_threshold, colour))
            except VisionError as exc:
                warnings.append(f"imagej: spot at ({s.u:.1f}, {s.v:.1f}) px: {exc}")
        if not measured:
            raise NoSpotError(f"{name}: the imagej method measured none of the {len(spots)} spots found")
        spots = measured
    elif method != "precise":
        raise VisionError(f"unknown centroid method '{method}' (precise or imagej)")
    return sorted(spots, key=lambda s: (round(s.v), s.u)), warnings


def _imagej_box(shape, spot: Spot, side: int) -> tuple[int, int, int, int]:
    """The box a person would draw around a spot: ``side`` px square, 0 for the whole photo."""
    h, w = shape[:2]
    if side <= 0:
        return 0, 0, w, h
    x0, y0 = int(round(spot.u - side / 2)), int(round(spot.v - side / 2))
    return max(x0, 0), max(y0, 0), min(x0 + side, w), min(y0 + side, h)
