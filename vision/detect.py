"""Laser-spot detection and the precise sub-pixel centroid.

Coordinates are pixels in OpenCV's convention (pixel centres at integer coordinates, ``u`` to the
right, ``v`` down); intensities are digital numbers (DN) of the photo. ImageJ reports the same
point at ``(u + 0.5, v + 0.5)``.

Detection, of a red (or green) laser on paper, cardboard or a wall as real cameras record it:
from a dim coloured spot to a white clipped core whose colour survives only in a red, orange,
pink (or pale green) rim, and spots hundreds of pixels wide.

1. candidates: on a 1/f-size block average (fast on 12-megapixel photos), the paper level (a
   tile percentile, so black markers do not sink it) is removed from the laser's channel and
   from its *colour excess* (the channel minus the brighter other one: ~0 on white paper, black
   ink and white glare alike). A region brighter than the paper in the laser's channel is a
   candidate as a whole when a few of its pixels are laser-coloured (the halo of a white core).
   The same on a coarse copy (~64 rows) finds spots too wide for the tiles, and clipped white
   blobs are candidates too (the cores of spots far past clipping).
2. each candidate, with a plane fitted to the box border as the local background (a box over
   :data:`MEASURE_SIDE` px on a shrunk copy), is measured (:class:`Evidence`) and rejected when
   it is not brighter than the paper in the laser's channel *and* in the luma (red ink: a
   phone's colour correction lifts its red above the paper's, but it takes light away), when
   its rim does not shift towards the laser's hue relative to the paper (white light of any
   kind, see :func:`_rim_shift`), when it is smaller than any lens-blurred spot, not a compact
   ellipse, or a JPEG fringe beside ink (weak, next to darker pixels, or dark at its centre).
   The spots left are ranked by the light they add (:attr:`Evidence.strength`).
3. centroid (``precise``): an elliptical profile fitted in linear light to the spot and its
   flanks; clipped pixels only bound the profile from below, so the centre of a clipped spot
   comes from the plateau's edge and the unclipped flanks (see :func:`_fit_profile`). In a
   4:2:0 JPEG an unclipped spot is fitted in the luma plus a fifth of the chroma difference Cr
   (see :data:`CHROMA_WEIGHT`). Its sigma propagates the asymmetry of the fit's residuals about
   the centre through the fit (see :func:`_centre_sigma`). Where printed ink lies under a spot,
   its pixels are left out; spots on ink are flagged.

With a laser-off reference photo the candidates come from the difference image, which holds
nothing but laser light, and fainter spots are believed. ``colour="auto"`` tries both lasers
and keeps the more convincing.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy.optimize import least_squares

from lasercal.vision.errors import NoSpotError, SpotCountError, VisionError
from lasercal.vision.imagej import measure as imagej_measure
from lasercal.vision.images import full_scale
from lasercal.vision.spot import CHANNEL, Evidence, Spot

LUMA = np.array([0.114, 0.587, 0.299])  # BGR weights of JPEG's luma (ITU-R BT.601)
CR = np.array([-0.0813, -0.4187, 0.5])  # BGR weights of JPEG's red chroma difference (Cr)
# An unclipped spot in a 4:2:0 JPEG is fitted in the luma plus this much of Cr. After colour
# correction a dim red spot leaves about a quarter of its red rise in the luma, twice as much in
# Cr; but Cr is stored at half resolution and quantised ~3x coarser, so its own centre is ~2x
# worse. Their JPEG errors are independent: measured on the phone renderer (JPEG quality 85-92,
# spots 0.3-0.5x clipping, speckle 0-0.2), 0.2 cuts the RMS error of red spots by ~15 % and of
# green ones by ~7 % (0.1-0.3 are within 3 % of it; 0 is the luma alone, 1.4 the red channel).
CHROMA_WEIGHT = 0.2
MAX_CANDIDATES = 50
FIT_STRAY = 1.0  # px
CLIP = 0.985  # a recorded value at or above this fraction of full scale is clipped
LUMA_CLIP = 0.97  # the same for the luma: JPEG ringing wobbles a white core by a few DN
HALO_CAP = 20.0
# The rim-shift rule (see _rim_shift): white light, whatever the paper, gives <= 1 in theory; a light
# whose colour temperature differs from the white balance, and the tone curve's shoulder, push it
# up: 1.92 measured for a white LED torch on brown paper (as a green laser), 1.75 for glare on red
# clips, up to 1.6 for glints in a lab, 1.0 for the renderer's glare. Laser rims: 2.6-20 on the real
# photos (the lowest, 2.6-2.8, an orange-rendered spot on beige paper), 2.35-20 on the renderer's
# spots from 10x to 30x clipping on bright paper (its white disks, whose rim holds no colour, less).
SHIFT_MIN = 2.2
# The channels a laser's rim is weighed against: its neighbours in wavelength. Broadband light of
# any colour temperature moves neighbouring channels least against each other (a tungsten lamp
# under a daylight white balance adds red ~1.5x green but ~2.5x blue), while a laser is far from
# them. Red: green only (blue is a channel away, and some cameras render a red laser magenta,
# blue rising with it). Green: red or blue, whichever shifts more (both are its neighbours).
NEIGHBOURS = {2: (1,), 1: (2, 0)}
# A green rim must shift against both neighbours by this much: broadband light of any colour
# temperature shifts green against one of them by <= 1 (a warm lamp's light is redder, a cool one's
# bluer than green); the renderer's green spots clear it up to 30x clipping.
SIDE_MIN = 1.2
# A surround whose laser channel outshines the others this much (linear) is no paper under room
# light: the laser's own halo fills the view (a tight crop), and the clipped core in it is the spot.
MONO = 20.0
# Laser light adds light: the luma rises by at least a quarter of the laser channel's weight in it
# times the channel's rise (a phone's colour matrix leaks up to half of it away: 0.48 measured for
# green on the renderer). Red objects and ink redden a patch while its other channels fall.
LIGHT_SHARE = 0.25
# A lens and demosaicing blur any spot by sigma >= 1 px: its blob (>= 15 % of its peak after the
# sigma-1 smoothing) covers >= 24 px. A hot photosite (one red 2x2 block) covers ~12.
MIN_BLOB = 20
MIN_FILL = 0.8  # area over the moment ellipse: 1 for an ellipse, ~0.95 cut, >= 0.91 for real spots
MAX_ASPECT = 2.5  # a beam 66 deg off the normal: far past any pose that aims a laser at a sheet


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


REASONS = {
    "dim": "not brighter than the paper (printed marks?)",
    "white": "white, not laser-coloured (reflections?)",
    "shape": "not a compact ellipse (a wire, a frame or an object's edge?)",
    "unlit": "coloured but adds too little light (a red object, ink or a sensor defect?)",
    "fringe": "a faint coloured fringe beside ink or a ring (JPEG artefact)",
    "stray": "its centre falls off its own laser-coloured light (ink beside a spot?)",
}


@dataclass(frozen=True)
class Rejection:
    """Why a candidate is not a laser spot (``kind`` is a key of :data:`REASONS`)."""

    kind: str
    u: float
    v: float
    evidence: Evidence | None = None

    def describe(self) -> str:
        """One line: where, why, and the evidence when it was measured."""
        ev = "" if self.evidence is None else f" ({self.evidence.describe()})"
        return f"at ({self.u:.0f}, {self.v:.0f}) px: {REASONS[self.kind]}{ev}"


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
    img: np.ndarray,
    colour: str = "red",
    reference: np.ndarray | None = None,
    k_sigma: float = 6.0,
    shrunk: dict | None = None,
) -> list[Candidate]:
    """Regions of laser-coloured light brighter than their surroundings, at two scales, and
    clipped white blobs (a spot's core, whose colour survives only in its rim).

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16
    colour : "red" or "green"
    reference : array like ``img`` or None, the same view with the laser off
    k_sigma : float, threshold in robust sigmas of the background
    shrunk : dict or None, shrunk copies of the photo by factor, shared between calls on one photo

    Returns
    -------
    list of Candidate, strongest first, at most 50
    """
    shrunk = {} if shrunk is None else shrunk
    h, w = img.shape[:2]
    src = cv2.subtract(img, reference) if reference is not None else img
    f = max(1, min(h, w) // 750)  # block size: ~750 rows keep spots of sigma >= 1 px visible
    # Block-average first: the colour excess of block means is close enough for finding
    # spots, and it spares full-resolution passes over 12-megapixel photos.
    small = _shrink(src, f) if reference is not None else _cached(shrunk, img, f)
    floor = 0.03 * full_scale(img)  # JPEG flattens paper to a noise-free level: keep a floor

    def noise_level(x):
        return max(k_sigma * _robust_sigma(x), floor)

    fine = _candidates_at(small, f, (h, w), colour, _highpass, noise_level)
    # A spot wider than the paper-level tiles lifts the paper level with it: look again on a
    # coarse copy (~64 rows) for spots tens to hundreds of px wide. There the scene, not noise,
    # sets the spread, so such a spot must rise over the photo's median by half the headroom left.
    big = max(1, min(h, w) // 64)
    coarse = []
    if big >= 4 * f:
        tiny = _shrink(small, big // f) if reference is not None else _cached(shrunk, small, big // f, f)

        def headroom(x):
            return max(0.5 * (full_scale(img) - float(np.median(tiny[..., CHANNEL[colour]]))), floor)

        coarse = _candidates_at(tiny, big // f * f, (h, w), colour, _median_pass, headroom, 3)
    white = _white_candidates(small, f, (h, w)) if src.ndim == 3 and reference is None else []
    white = [c for c in white if not any(_inside(c, o) for o in fine)]  # a core already found
    return (coarse + white + fine)[:MAX_CANDIDATES]  # the few large ones first: fine ones abound


def _inside(c: Candidate, o: Candidate) -> bool:
    """Whether ``c``'s centre lies in ``o``'s box."""
    return o.box[0] <= c.u < o.box[2] and o.box[1] <= c.v < o.box[3]


def _cached(shrunk: dict, img: np.ndarray, f: int, base: int = 1) -> np.ndarray:
    """``img`` (itself shrunk by ``base``) shrunk by ``f``, computed once per photo in ``shrunk``."""
    if base * f not in shrunk:
        shrunk[base * f] = _shrink(img, f)
    return shrunk[base * f]


def _octave(shrunk: dict, img: np.ndarray, k: int) -> np.ndarray:
    """``img`` shrunk by ``k``, a power of 2, each octave from the one before (kept in ``shrunk``
    under the key ``-k``, apart from :func:`_cached`'s)."""
    if -k not in shrunk:
        shrunk[-k] = _shrink(img if k == 2 else _octave(shrunk, img, k // 2), 2)
    return shrunk[-k]


def _shrink(img: np.ndarray, f: int) -> np.ndarray:
    """Block average by ``f`` (INTER_AREA), or the image itself for ``f`` = 1."""
    h, w = img.shape[:2]
    if f <= 1:
        return img
    return cv2.resize(img, (max(w // f, 1), max(h // f, 1)), interpolation=cv2.INTER_AREA)


def _median_pass(small: np.ndarray) -> np.ndarray:
    """Subtract the photo's median: the paper level for spots too large for :func:`_highpass`."""
    return small - np.float32(np.median(small))


def _candidates_at(
    small: np.ndarray,
    f: int,
    shape: tuple[int, int],
    colour: str,
    paper_level,
    threshold,
    min_px: int = 1,
) -> list[Candidate]:
    """Candidates found on a copy of the photo shrunk by ``f`` (see :func:`find_candidates`).

    Parameters
    ----------
    small : (h/f, w/f[, 3]) array, the shrunk photo
    f : int, the shrink factor; shape : (h, w) of the full photo, px
    paper_level : callable, (h, w) float32 array -> the same with the paper level removed
    threshold : callable, that array -> the rise that stands out, DN
    min_px : int, smallest component kept, px of ``small``

    Returns
    -------
    list of Candidate (full-resolution boxes), strongest first
    """
    ch = CHANNEL[colour]
    laser, excess = _channels(small, ch)
    strength = paper_level(excess.astype(np.float32))
    if small.ndim == 2:
        mask = strength > threshold(strength)
    else:
        # Laser light is both coloured and brighter than its surroundings; JPEG colour
        # fringes at ink edges are coloured but not brighter, red ink neither.
        bright = paper_level(laser.astype(np.float32))
        lit = bright > threshold(bright)
        # A clipped spot is coloured only in a thin halo around its white core, and only faintly
        # when the photo is bright: a region of bright pixels is a candidate as a whole when a few
        # of its pixels are laser-coloured, at a third of the threshold.
        faint = lit & (strength > threshold(strength) / 3)
        n, labels = cv2.connectedComponents(lit.astype(np.uint8), connectivity=8)
        hit = np.bincount(labels[faint], minlength=n) >= 2
        hit[0] = False
        mask = hit[labels]
    return _boxes(mask, strength, f, shape, min_px)


def _white_candidates(small: np.ndarray, f: int, shape: tuple[int, int]) -> list[Candidate]:
    """Clipped white blobs: the core of a spot exposed far past clipping, whose halo may be too
    wide or too faint to stand out from the paper (its rim decides, in :func:`measure_spot`)."""
    white = (small >= LUMA_CLIP * full_scale(small)).all(axis=2)
    return _boxes(white, white.astype(np.float32), f, shape, 2)


def _boxes(
    mask: np.ndarray, strength: np.ndarray, f: int, shape: tuple[int, int], min_px: int
) -> list[Candidate]:
    """One Candidate per connected region of ``mask`` (a shrunk copy, factor ``f``), strongest
    first: its box (3x the region, full resolution) and its centre."""
    h, w = shape
    # Speckle and JPEG blocks break a spot's mask into pieces: join pieces a few pixels apart.
    mask = cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8))
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return []
    on = labels > 0  # few pixels: a scatter-max over them is cheap
    best = np.full(n, -np.inf)
    np.maximum.at(best, labels[on], strength[on])
    best[1:][stats[1:, 4] < min_px + 24] = -np.inf  # the 5x5 dilation adds 24 px to a lone pixel
    order = [i for i in np.argsort(-best[1:])[:MAX_CANDIDATES] + 1 if np.isfinite(best[i])]
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
    yy, xx = _border_pixels(h, w)
    A = np.column_stack([np.ones(len(xx)), xx - w / 2, yy - h / 2])
    vals = roi[yy, xx].reshape(len(xx), c).astype(float)
    coef, *_ = np.linalg.lstsq(A, vals, rcond=None)
    res = vals - A @ coef
    for _ in range(3):  # drop border pixels crossed by ink or a neighbour spot; a big dot needs a few rounds
        mad = 1.4826 * np.median(np.abs(res - np.median(res, 0)), 0) + 1e-6
        keep = np.all(np.abs(vals - A @ coef) < 3 * mad + 1, 1)
        if keep.sum() < 8:
            break
        coef, *_ = np.linalg.lstsq(A[keep], vals[keep], rcond=None)
        res = vals[keep] - A[keep] @ coef
    # Robust: ink fringes that survive on the border must not pass for noise. Quantisation
    # keeps at least ~0.3 DN.
    noise = np.maximum(1.4826 * np.median(np.abs(res - np.median(res, 0)), 0), 0.3)
    x, y = (np.arange(w) - w / 2)[None, :, None], (np.arange(h) - h / 2)[:, None, None]
    bg = coef[0] + x * coef[1] + y * coef[2]
    return bg.astype(np.float32), noise


def _border_pixels(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a box's 2-px frame, each pixel once (no full-size mask: boxes can be large)."""
    rows = np.unique(np.r_[0 : min(2, h), max(h - 2, 0) : h])
    inner = np.setdiff1d(np.arange(h), rows)
    cols = np.unique(np.r_[0 : min(2, w), max(w - 2, 0) : w])
    yy = np.concatenate([np.repeat(rows, w), np.repeat(inner, len(cols))])
    xx = np.concatenate([np.tile(np.arange(w), len(rows)), np.tile(cols, len(inner))])
    order = np.lexsort((xx, yy))  # row by row, as np.nonzero of a mask gives them
    return yy[order], xx[order]


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


def _linear(x: np.ndarray, full: float, gamma: float) -> np.ndarray:
    """Encoded DN -> linear DN (same full scale)."""
    return full * np.clip(x / full, 0, None) ** gamma


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
        q = (np.exp(p[3]) * dx) ** 2 + (p[5] * dx + np.exp(p[4]) * dy) ** 2
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
        sm = cv2.GaussianBlur(sig, (0, 0), 1.0)  # single noisy border pixels are no reason to grow
        edge = max(sm[0].max(), sm[-1].max(), sm[:, 0].max(), sm[:, -1].max())
        whole = (x0, y0, x1, y1) == (0, 0, w, h) or max(x1 - x0, y1 - y0) >= GROW_MAX
        if edge < max(0.05 * peak_d, 3 * noise[ch]) or whole or attempt == 3:
            break
        gx, gy = (x1 - x0) // 2, (y1 - y0) // 2
        x0, y0, x1, y1 = max(x0 - gx, 0), max(y0 - gy, 0), min(x1 + gx, w), min(y1 + gy, h)
    # Not brighter than the paper: ink or a JPEG fringe, not light. A reference photo
    # removes ink and fringes, so fainter spots are believed then.
    contrast = (0.05 if reference is not None else 0.08) * full
    smooth = cv2.GaussianBlur(sig, (0, 0), 1.0)  # speckle would split a spot into several blobs
    plain = img[y0:y1, x0:x1].astype(np.float32).reshape(roi.shape)  # the photo itself, not a difference
    base = plain - delta  # what the photo would show without the laser (paper, or reference + paper)
    if img.ndim == 3 and _surround(base, ch, full, gamma) >= MONO:
        return _core_in_halo(plain, delta, cand, (x0, y0), ch, full, noise, peak_d, colour, gamma)
    need = max(8 * noise[ch], contrast)
    thr = max(4 * noise[ch], 0.15 * peak_d)
    bright = (smooth > thr).astype(np.uint8)
    ink = _ink(plain, base, ch) if img.ndim == 3 else None
    if ink is not None:
        # A printed cross under the spot cuts it into pieces: bridge them over the ink.
        bright |= (ink & cv2.dilate(bright, np.ones((7, 7), np.uint8)).astype(bool)).astype(np.uint8)
    n, labels = cv2.connectedComponents(bright, connectivity=8)
    if n <= 1:
        return Rejection(
            "dim", cand.u, cand.v, _evidence(plain, delta, None, ch, full, noise, peak_d, need, colour, gamma)
        )
    # The brightest blob, unless it is another candidate's (a grown box may reach a brighter
    # neighbour, such as red ink, that is measured on its own).
    ours = labels > 0
    mine = _label_at(labels, cand.u - x0, cand.v - y0)
    for o in others:
        theirs = _label_at(labels, o.u - x0, o.v - y0)
        if theirs and theirs != mine:
            ours &= labels != theirs
    if not ours.any():
        ours = labels > 0
    iy, ix = np.unravel_index(np.argmax(np.where(ours, smooth, -np.inf)), sig.shape)
    blob = labels == labels[iy, ix]
    raw = plain[..., ch]
    clipped = raw >= CLIP * full
    if clipped[blob].any():
        # A clipped spot on bright paper exceeds it by no more than the headroom left: clipped and
        # half the headroom (or 8 sigma) brighter than the paper is bright enough, where the paper
        # is textured (a large spot's box holds the scene) at least 3 sigma.
        headroom = 0.5 * (full - float(np.median(base[..., ch])))
        need = max(3 * noise[ch], min(8 * noise[ch], contrast, headroom))
    if peak_d < need or blob.sum() < MIN_BLOB:  # dim or tiny: no need to weigh its colour
        return Rejection(
            "dim", cand.u, cand.v, _evidence(plain, delta, blob, ch, full, noise, peak_d, need, colour)
        )
    ev = _evidence(plain, delta, blob, ch, full, noise, peak_d, need, colour, gamma)
    # Laser light adds light: the luma rises too (a lone bright pixel is JPEG ringing or noise).
    if ev.light * full < _light_need(noise, full):
        return Rejection("dim", cand.u, cand.v, ev)
    if img.ndim == 3 and ev.light < LIGHT_SHARE * LUMA[ch] * ev.excess:
        return Rejection("unlit", cand.u, cand.v, ev)
    # A JPEG fringe is colour without light: its luma, kept at full resolution, barely rises.
    faint = ev.clipped_px == 0 and ev.light * full < 2 * _light_need(noise, full)
    if img.ndim == 3 and reference is None and peak_d < 0.15 * full and faint:
        # JPEG's coarse colour planes leave a faint laser-coloured fringe beside ink: a
        # weak blob next to pixels darker than the paper in the other channels is one.
        around = cv2.dilate(blob.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool)
        if np.max(np.delete(delta, ch, axis=2), axis=2)[around].min() < -0.15 * full:
            return Rejection("fringe", cand.u, cand.v, ev)
    if img.ndim == 3:
        # A white reflection (clipped or not) is as bright in the other channels as in the laser's;
        # laser light keeps its colour in a halo around a clipped white core.
        if ev.rule is None:
            return Rejection("white", cand.u, cand.v, ev)
    # A beam on a plane makes an ellipse (aspect 1/cos(tilt)): a blob that fills its own moment
    # ellipse poorly, or is longer than a beam at 66 deg makes, is a wire, a frame or an edge.
    fill, aspect = _ellipse_fit(blob)
    if fill < MIN_FILL or aspect > MAX_ASPECT:
        return Rejection("shape", cand.u, cand.v, ev)
        # JPEG ringing beside black ink is faintly coloured; laser light is strongly so, except in
        # the thin halo of a clipped core (ringing never clips).
        colour_ex = cv2.blur(sig - np.max(np.delete(delta, ch, axis=2), axis=2), (3, 3))
        halo = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        if ev.clipped_px == 0 and colour_ex[halo].max(initial=0) < max(6 * noise[ch], contrast / 2):
            return Rejection("white", cand.u, cand.v, ev)
    exclude = np.zeros(sig.shape, bool)
    for o in others:
        ox, oy = int(round(o.u)) - x0, int(round(o.v)) - y0
        if 0 <= ox < sig.shape[1] and 0 <= oy < sig.shape[0] and labels[oy, ox] > 0 and not blob[oy, ox]:
            exclude |= labels == labels[oy, ox]
    r_eq = np.sqrt(blob.sum() / np.pi)
    m = cv2.moments(blob.astype(np.uint8), binaryImage=True)
    start = (m["m10"] / m["m00"], m["m01"] / m["m00"])
    use_luma = luma and img.ndim == 3
    cen = delta @ LUMA if use_luma else sig
    u, v, wgt = _weighted_centroid(cen, start, 1.1 * r_eq + 1, exclude)
    # A spot is brightest near its centre; a ring (JPEG fringe around ink) is dark there.
    if smooth[int(round(v)), int(round(u))] < 0.3 * smooth[blob].max() and ink is None and faint:
        return Rejection("fringe", cand.u, cand.v, ev)
    Y, X = np.mgrid[: sig.shape[0], : sig.shape[1]]
    on_ink = ink is not None and bool(((np.hypot(X - u, Y - v) <= 1.5 * r_eq + 2) & ink).any())
    saturated = bool(clipped[blob].any())
    # Fit the profile in linear light over the spot and its flanks; clipped pixels bound it
    # from below, ink and other spots are left out.
    rec, under = (plain @ LUMA, base @ LUMA) if use_luma else (raw, base[..., ch])
    top = (LUMA_CLIP if use_luma else CLIP) * full
    lin_base = _linear(under, full, gamma)
    window = (np.hypot(X - u, Y - v) <= 2 * r_eq + 3) & ~exclude
    if ink is not None:
        window &= ~ink
    # The background's noise in linear units: the encoding's slope at the paper level.
    slope = gamma * float(np.median(np.clip(under[window] / full, 1e-3, 1))) ** (gamma - 1)
    n_rec = float(noise @ LUMA) if use_luma else float(noise[ch])
    d_fit, n_fit, clip_fit = _linear(rec, full, gamma) - lin_base, n_rec * slope, rec >= top
    if use_luma and not (clip_fit[window].any() or clipped[window].any()):
        # An unclipped spot in a 4:2:0 JPEG: the luma plus a little of the chroma (see CHROMA_WEIGHT).
        d_fit = (plain - base) @ _laser_plane(ch)
        n_fit = _border_noise(d_fit)
    fit = _fit_profile(
        d_fit,
        window,
        clip_fit,
        _linear(np.full_like(rec, top), full, gamma) - lin_base,
        (u, v),
        r_eq,
        n_fit,
    )
    # A fit that strays over a pixel from the windowed centroid fell for clutter in its wider
    # window (JPEG fringes of nearby ink): keep the centroid then.
    if fit is not None and (on_ink or np.hypot(fit[0] - u, fit[1] - v) <= FIT_STRAY):
        u, v, su, sv = fit
    elif on_ink:
        return Rejection("dim", cand.u, cand.v, ev)
    else:
        su, sv = _centroid_sigma(cen, wgt, u, v)
    # Laser light lies where its colour is. Red ink on bright paper can clip in red and pass for a
    # clipped spot, but its luma is darker than the paper's: the luma centroid over it runs off to
    # whatever is brighter nearby, off the blob.
    near = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8))
    if not _label_at(near, u, v):
        return Rejection("stray", cand.u, cand.v, ev)
    # A blob cut by the photo's edge shows only part of its light, and its centre is extrapolated.
    cut = (x0 == 0 and blob[:, 0].any()) or (y0 == 0 and blob[0].any())
    cut |= (x0 + blob.shape[1] == w and blob[:, -1].any()) or (y0 + blob.shape[0] == h and blob[-1].any())
    return Spot(
        u + x0,
        v + y0,
        su,
        sv,
        float(raw[blob].max()),
        saturated,
        int(blob.sum()),
        on_ink=on_ink,
        evidence=replace(ev, cut=bool(cut)),
    )


def _ellipse_fit(blob: np.ndarray) -> tuple[float, float]:
    """How well a blob fills the ellipse of its second moments, and that ellipse's aspect ratio.

    A uniform ellipse of semi-axes a, b has moment eigenvalues a**2 / 4 and b**2 / 4, so the
    ellipse of eigenvalues l1 >= l2 has area 4 pi sqrt(l1 l2).

    Returns
    -------
    fill : float, area / (4 pi sqrt(l1 l2)) (1 for an ellipse); aspect : float, sqrt(l1 / l2)
    """
    m = cv2.moments(blob.astype(np.uint8), binaryImage=True)
    if m["m00"] < 4:
        return 1.0, 1.0
    a, b, c = m["mu20"] / m["m00"], m["mu11"] / m["m00"], m["mu02"] / m["m00"]
    root = np.sqrt(((a - c) / 2) ** 2 + b**2)
    l1, l2 = (a + c) / 2 + root, max((a + c) / 2 - root, 1 / 12)  # a 1-px line is 1/12 px**2 wide
    return float(m["m00"] / (4 * np.pi * np.sqrt(l1 * l2))), float(np.sqrt(l1 / l2))


def _core_in_halo(
    plain: np.ndarray,
    delta: np.ndarray,
    cand: Candidate,
    origin: tuple[int, int],
    ch: int,
    full: float,
    noise: np.ndarray,
    peak_d: float,
    colour: str,
    gamma: float,
) -> Spot | Rejection:
    """A spot whose own halo fills the box (a tight crop): its clipped white core, in a surround of
    nearly monochromatic laser light (see :data:`MONO`), is the spot; the centre is the core's.

    The surround is the laser's light, so the rim rule has no paper to compare with and the laser's
    channel is clipped over the core and most of the halo: only the core's outline is left. The
    sigma is a floor, the pixel quantisation of a disc's outline: each of its ~2 pi r edge pixels
    is in or out (variance 1/12) at a lever r cos(theta), so var = pi r**3 / (12 N**2) = 1 / (12 pi r)
    for N = pi r**2 pixels; speckle on the core's edge adds to it.
    """
    white = (plain >= LUMA_CLIP * full).all(axis=2).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(white, connectivity=8)
    if n <= 1 or stats[1:, 4].max() < 4:
        return Rejection("dim", cand.u, cand.v, None)
    i = 1 + int(np.argmax(stats[1:, 4]))
    blob = labels == i
    ev = _evidence(plain, delta, blob, ch, full, noise, peak_d, peak_d, colour, gamma)
    if ev.rule != "view":
        return Rejection("white", cand.u, cand.v, ev)
    area = int(stats[i, 4])
    sigma = float(1 / np.sqrt(12 * np.pi * np.sqrt(area / np.pi)))
    u, v = cents[i]
    x0, y0 = origin
    raw = plain[..., ch]
    return Spot(u + x0, v + y0, sigma, sigma, float(raw[blob].max()), True, area, evidence=ev)


def _label_at(labels: np.ndarray, x: float, y: float) -> int:
    """The label under a point of the box (0 outside the box or on the background)."""
    ix, iy = int(round(x)), int(round(y))
    if 0 <= iy < labels.shape[0] and 0 <= ix < labels.shape[1]:
        return int(labels[iy, ix])
    return 0


def _laser_plane(ch: int) -> np.ndarray:
    """BGR weights of the plane an unclipped spot is fitted in, for a 4:2:0 JPEG: the luma plus
    :data:`CHROMA_WEIGHT` times the chroma difference (Cr) signed so that the laser raises it."""
    return (LUMA + CHROMA_WEIGHT * (1 if ch == 2 else -1) * CR).astype(np.float32)


def _border_noise(x: np.ndarray) -> float:
    """Robust sigma of a plane over its box's 2-px border (the background there), at least 0.3 DN."""
    border = np.concatenate([x[:2].ravel(), x[-2:].ravel(), x[2:-2, :2].ravel(), x[2:-2, -2:].ravel()])
    return max(_robust_sigma(border - np.median(border)), 0.3)


def _evidence(
    plain: np.ndarray,
    delta: np.ndarray,
    blob: np.ndarray | None,
    ch: int,
    full: float,
    noise: np.ndarray,
    peak_d: float,
    need: float,
    colour: str,
    gamma: float | None = None,
) -> Evidence:
    """Measure what a candidate looks like (see :class:`Evidence`).

    Parameters
    ----------
    plain : (h, w, c) array, the photo in the candidate's box, DN
    delta : (h, w, c) array, its excess over the local background, DN
    blob : (h, w) bool array, the spot's pixels, or None when nothing stood out
    ch : int, the laser's channel; full : float, full scale, DN
    noise : (c,) array, the background's noise per channel, DN
    peak_d : float, peak excess of the laser's channel, DN
    need : float, the excess a spot needs, DN
    colour : str, the laser colour tried
    gamma : float or None, the photo's encoding gamma; None skips the colour rule and the flux (a
        candidate already rejected as dim)
    """
    area = 0 if blob is None else int(blob.sum())
    grey = plain.shape[2] == 1
    clipped = white = 0
    halo = None
    light = peak_d
    level = 0.0 if blob is None else float(plain[..., ch][blob].max()) / full
    if blob is not None:
        clipped = int((plain[..., ch][blob] >= CLIP * full).sum())
        white_px = (plain >= LUMA_CLIP * full).all(axis=2)
        white = int(white_px[blob].sum())
        if not grey:
            luma = cv2.GaussianBlur(delta @ LUMA, (0, 0), 1.0)
            light = float(luma[blob].max())
            # The halo: pixels of the spot and just around it not clipped in all channels, with a
            # clear excess. Summed over the halo: a clipped spot's colour may survive in a rim only
            # one or two pixels wide, which JPEG's half-resolution colour dilutes further.
            lase, other = delta[..., ch], np.max(np.delete(delta, ch, axis=2), axis=2)
            ring = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~white_px
            ring &= lase > max(0.1 * peak_d, 4 * noise[ch])
            if ring.sum() >= 3:
                total = float(lase[ring].sum())
                halo = total / max(float(np.maximum(other[ring], 0).sum()), total / HALO_CAP)
            else:
                halo = 1.0  # all white: nothing says laser
    rim = paper = shift = None
    rule = "grey" if grey else None
    s_colour = 1.0
    flux = 0.0
    if blob is not None and gamma is not None:
        base = plain - delta
        flux = float(
            (_linear(plain[..., ch][blob], full, gamma) - _linear(base[..., ch][blob], full, gamma)).sum()
        )
    if blob is not None and not grey and gamma is not None:
        rim, paper, _ = _rim_shift(plain, base, blob, ch, full, gamma, max(0.03 * peak_d, 4 * noise[ch]))
        shift = rim / max(1.0, paper)
        s_colour = _score(np.log(shift / SHIFT_MIN), 0.25)
        if shift >= SHIFT_MIN:
            rule = "rim"
        elif white and _surround(base, ch, full, gamma) >= MONO:
            rule, s_colour = "view", 0.75
    s_excess = _score(np.log(max(peak_d, 1e-6) / need), 0.25)
    s_light = _score(np.log(max(light, 1e-6) / _light_need(noise, full)), 0.25)
    return Evidence(
        None if grey else colour,
        peak_d / full,
        peak_d / float(noise[ch]),
        level,
        light / full,
        halo,
        clipped,
        white,
        area,
        float(min(s_excess, s_colour, s_light) if rule != "view" else s_colour),
        rim,
        paper,
        shift,
        rule,
        flux,
    )


def _rim_shift(
    plain: np.ndarray, base: np.ndarray, blob: np.ndarray, ch: int, full: float, gamma: float, thr: float
) -> tuple[float, float, int]:
    """Colour of the light a candidate adds, against the colour of the paper under it (linear light).

    White light, whatever the surface, adds light in the surface's own colour (diffuse) or in the
    light's own colour, white (specular): the laser channel's share of the added light, over
    ``max(1, paper ratio)``, is at most 1. A laser adds light in its own channel only (the others get
    cross-talk, blooming and the colour matrix's leak), so its rim shifts towards the laser's hue
    whatever the paper's colour. Pixels clipped in another channel carry no ratio and are left out;
    so are those clipped in the laser's channel (a lower bound only), where enough others remain.

    The laser's channel is weighed against its neighbours in wavelength (:data:`NEIGHBOURS`).
    Two parts of the rim are measured and the larger shift kept: the whole unclipped rim, and its
    faint outer part (the lower half of the headroom over the paper), where neither the tone curve's
    shoulder (which squeezes the brighter channel) nor blooming (which whitens the rim of a spot far
    past clipping) tilts the ratio, but which is thin and noisy on a bright paper.

    Parameters
    ----------
    plain, base : (h, w, 3) arrays, the photo and the local background (paper) in the box, DN
    blob : (h, w) bool array, the candidate's pixels
    ch : int, the laser's channel; full : float, full scale, DN; gamma : float, encoding gamma
    thr : float, excess of the laser's channel (DN, encoded) a rim pixel needs

    Returns
    -------
    added : float, laser channel's added light over a neighbouring channel's, summed over the rim
        (linear, capped at HALO_CAP), for the rim part that shifts most
    paper : float, the same ratio of the background light under that rim (median)
    n : int, rim pixels used
    """
    ys, xs = np.nonzero(blob)  # work on the blob's bounding box (grown by the rim): boxes can be large
    y0, x0 = max(ys.min() - 5, 0), max(xs.min() - 5, 0)
    win = (slice(y0, ys.max() + 6), slice(x0, xs.max() + 6))
    plain, base, blob = plain[win], base[win], blob[win]
    rim = cv2.dilate(blob.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool)
    rim &= (np.delete(plain, ch, axis=2) < CLIP * full).all(axis=2) & (plain[..., ch] - base[..., ch] > thr)
    free = rim & (plain[..., ch] < CLIP * full)
    if free.sum() >= 6:
        rim = free
    low = rim & (plain.max(axis=2) < 0.5 * (full + base.max(axis=2)))
    parts = [rim, low] if low.sum() >= 6 else [rim]
    best = (0.0, 1.0, 1.0)
    for part in parts:
        if part.sum() < 3:
            continue
        lp, lb = _linear(plain[part], full, gamma), _linear(np.maximum(base[part], 0.5), full, gamma)
        add = (lp - lb).sum(0)
        shifts = []
        for o in NEIGHBOURS[ch]:
            added = min(float(add[ch] / max(add[o], add[ch] / HALO_CAP, 1e-9)), HALO_CAP)
            paper = float(np.median(lb[:, ch] / np.maximum(lb[:, o], 1e-6)))
            shifts.append((added / max(1.0, paper), added, paper))
        # Broadband light shifts green against one neighbour at most (warm light towards red, cool
        # towards blue); a green laser shifts against both.
        side = min(shifts)
        best = max(best, *shifts) if side[0] >= SIDE_MIN else max(best, side)
    return best[1], best[2], int(rim.sum())


def _surround(base: np.ndarray, ch: int, full: float, gamma: float) -> float:
    """How much the laser's channel outshines the brighter other one in the box's surround (median
    of the 2-px border of the background, linear light)."""
    border = np.concatenate(
        [
            base[:2].reshape(-1, 3),
            base[-2:].reshape(-1, 3),
            base[:, :2].reshape(-1, 3),
            base[:, -2:].reshape(-1, 3),
        ]
    )
    lin = _linear(np.median(np.maximum(border, 0.5), axis=0), full, gamma)
    return float(lin[ch] / max(np.delete(lin, ch).max(), 1e-6))


def _light_need(noise: np.ndarray, full: float) -> float:
    """The rise of the luma a spot needs, DN: 4 sigma of the paper's luma noise, at least 1.5 % of
    full scale (colour correction leaves a dim red spot only ~1/3 of its red rise in the luma)."""
    return max(4 * float(noise @ LUMA) if noise.size == 3 else 4 * float(noise[0]), 0.015 * full)


def _score(x: float, scale: float) -> float:
    """Logistic score of a margin ``x`` over a threshold: 0.5 at it, -> 1 far above."""
    return float(1 / (1 + np.exp(-np.clip(x / scale, -50, 50))))


def _strength(s: Spot) -> float:
    """How convincing a spot is, to rank it against others (see :attr:`Evidence.strength`)."""
    return 0.0 if s.evidence is None else s.evidence.strength


def _dedupe(spots: list[Spot]) -> list[Spot]:
    """Drop spots found twice: two candidates of one spot converge within its radius."""
    out: list[Spot] = []
    # Of two measurements of one spot, keep the one whose blob holds more of its light.
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
    colour : "red", "green" or "auto" (try both; the colour taken is each spot's ``evidence.colour``)
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
    warnings = []
    if colour == "auto":
        colour, spots, rejected, note = _auto_colour(img, reference, gamma, luma)
        if note:
            warnings.append(note)
    elif colour in CHANNEL:
        spots, rejected = _find(img, colour, reference, gamma, luma)
    else:
        raise VisionError(f"unknown laser colour '{colour}' (red, green or auto)")
    if img.ndim == 2:
        warnings.append("grey photo: white reflections cannot be told from laser light")
    if not spots:
        kinds = [k for k in REASONS if any(r.kind == k for r in rejected)]
        counts = ", ".join(f"{sum(r.kind == k for r in rejected)} {REASONS[k]}" for k in kinds)
        detail = f"; rejected: {counts}" if kinds else ""
        if rejected:  # the strongest candidate's evidence says how close it came
            best = max(rejected, key=lambda r: -1 if r.evidence is None else r.evidence.confidence)
            detail += f"; best candidate {best.describe()}"
        raise NoSpotError(f"{name}: no {colour} laser spot found{detail}{_white_blobs(img)}")
    if expect is not None and len(spots) > expect:
        spots, note = _keep_strongest(spots, expect, name)
        warnings.append(note)
    for sp in spots:
        if sp.evidence is not None and sp.evidence.cut:
            warnings.append(
                f"spot at ({sp.u:.1f}, {sp.v:.1f}) px is cut by the photo's edge: its centre is extrapolated "
                "from the part in view, and its sigma does not count that"
            )
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


CLOSE = 0.5  # a runner-up this close to the weakest kept spot, in strength, is not ruled out


def _keep_strongest(spots: list[Spot], expect: int, name: str) -> tuple[list[Spot], str]:
    """The ``expect`` most convincing spots, and a warning naming the others.

    One laser makes spots of about the same light (flux) wherever it lands; glints, LEDs and red
    objects that pass every rule are mostly far weaker. When the runner-up comes within
    :data:`CLOSE` of the weakest kept spot the photo cannot say which is the laser: both are named,
    with their confidence, and the photo is lost.

    Raises
    ------
    SpotCountError
        The runner-up is close in strength to the weakest kept spot.
    """
    ranked = sorted(spots, key=_strength, reverse=True)
    kept, rest = ranked[:expect], ranked[expect:]

    def where(s: Spot) -> str:
        return (
            f"({s.u:.1f}, {s.v:.1f}) px (confidence {s.evidence.confidence:.2f}, strength {_strength(s):.3g})"
        )

    if _strength(rest[0]) >= CLOSE * _strength(kept[-1]):
        raise SpotCountError(
            f"{name}: {len(spots)} spots found where {expect} {'is' if expect == 1 else 'are'} expected, "
            f"close in evidence: {'; '.join(where(s) for s in ranked[:6])}{' ...' if len(spots) > 6 else ''} "
            "(use --expect N for photos with several spots)"
        )
    others = "; ".join(where(s) for s in rest[:3]) + (" ..." if len(rest) > 3 else "")
    return kept, f"kept the {expect} most convincing spot{'s' * (expect > 1)}; weaker candidates: {others}"


def _white_blobs(img: np.ndarray, min_px: int = 20) -> str:
    """A note on clipped white blobs, for a photo without a spot: a laser spot exposed far beyond
    clipping can lose the last of its colour and look like a reflection."""
    if img.ndim == 2:
        return ""
    white = (img >= LUMA_CLIP * full_scale(img)).all(axis=2).astype(np.uint8)
    n, _, stats, cents = cv2.connectedComponentsWithStats(white, connectivity=8)
    big = [i for i in range(1, n) if stats[i, 4] >= min_px]
    if not big:
        return ""
    i = max(big, key=lambda i: stats[i, 4])
    return (
        f"; {len(big)} white clipped blob{'s' * (len(big) > 1)} without laser colour, the largest "
        f"{stats[i, 4]} px at ({cents[i, 0]:.0f}, {cents[i, 1]:.0f}) px: a reflection, or a laser spot "
        "so overexposed that its colour is gone (lower the exposure, or use a laser-off reference)"
    )


def _find(
    img: np.ndarray,
    colour: str,
    reference: np.ndarray | None,
    gamma: float,
    luma: bool,
    shrunk: dict | None = None,
) -> tuple[list[Spot], list[Rejection]]:
    """Spots of one laser colour, and the candidates rejected."""
    shrunk = {} if shrunk is None else shrunk
    refs: dict[int, np.ndarray] = {}
    cands = find_candidates(img, colour, reference, shrunk=shrunk)
    found, rejected = [], []
    for c in cands:
        others = [o for o in cands if o is not c]
        side = max(c.box[2] - c.box[0], c.box[3] - c.box[1])
        k = 1 if side <= MEASURE_SIDE else 2 ** int(np.ceil(np.log2(side / MEASURE_SIDE)))  # a pyramid
        if k <= 1:
            r = measure_spot(img, c, colour, reference, others, gamma, luma)
        else:
            # A spot tens to hundreds of px wide is measured on a shrunk copy of the photo: its
            # centre is known to a fraction of its width anyway, and the fit stays small and fast.
            # It is fitted in the luma: the laser's channel of so large a spot is clipped over a
            # wide, speckle-ragged plateau, while the others still draw its profile.
            small = _octave(shrunk, img, k)
            if reference is not None and k not in refs:
                refs[k] = _shrink(reference, k)
            ref = refs.get(k)
            r = _grown(
                measure_spot(small, _shrunk(c, k), colour, ref, [_shrunk(o, k) for o in others], gamma, True),
                k,
            )
        (rejected if isinstance(r, Rejection) else found).append(r)
    return _dedupe(found), rejected


MEASURE_SIDE = 160  # px: a candidate's box wider than this is measured on a shrunk copy
GROW_MAX = 2 * MEASURE_SIDE  # px: a box grows no further (larger spots are the coarse pass's)


def _shrunk(c: Candidate, k: int) -> Candidate:
    """A candidate in a copy of the photo shrunk by ``k`` (pixel centres: (u + 0.5) / k - 0.5)."""
    return Candidate(tuple(int(b) // k for b in c.box), (c.u + 0.5) / k - 0.5, (c.v + 0.5) / k - 0.5)


def _grown(r: Spot | Rejection, k: int) -> Spot | Rejection:
    """A spot or rejection measured on a copy shrunk by ``k``, in the full photo's pixels."""
    u, v = (r.u + 0.5) * k - 0.5, (r.v + 0.5) * k - 0.5
    if isinstance(r, Rejection):
        return replace(r, u=u, v=v)
    su = None if r.sigma_u is None else r.sigma_u * k
    sv = None if r.sigma_v is None else r.sigma_v * k
    ev = r.evidence
    if ev is not None:
        k2 = k * k
        ev = replace(
            ev, clipped_px=ev.clipped_px * k2, white_px=ev.white_px * k2, area=ev.area * k2, flux=ev.flux * k2
        )
    return replace(r, u=u, v=v, sigma_u=su, sigma_v=sv, area=r.area * k * k, evidence=ev)


def _auto_colour(
    img: np.ndarray, reference: np.ndarray | None, gamma: float, luma: bool
) -> tuple[str, list[Spot], list[Rejection], str | None]:
    """Decide the laser's colour from the photo: the colour whose spots are the more convincing.

    Returns
    -------
    colour : "red" or "green" ("red or green" when neither has a spot)
    spots, rejected : of that colour (rejected: of both when neither has a spot)
    note : str or None, a warning when both colours show spots
    """
    if img.ndim == 2:
        return "red", *_find(img, "red", reference, gamma, luma), None  # one channel: colour is moot
    shrunk: dict[int, np.ndarray] = {}  # one photo, two colours: shrink it once
    tries = {c: _find(img, c, reference, gamma, luma, shrunk) for c in CHANNEL}
    score = {c: max((_strength(s) for s in spots), default=0.0) for c, (spots, _) in tries.items()}
    best = max(score, key=score.get)
    if score[best] == 0:
        return "red or green", [], tries["red"][1] + tries["green"][1], None
    other = next(c for c in CHANNEL if c != best)
    note = None
    if tries[other][0]:
        note = (
            f"both red and green spots found: measured {best} (strength {score[best]:.3g} against "
            f"{score[other]:.3g}); give --color to choose"
        )
    return best, *tries[best], note


def _imagej_box(shape, spot: Spot, side: int) -> tuple[int, int, int, int]:
    """The box a person would draw around a spot: ``side`` px square, 0 for the whole photo."""
    h, w = shape[:2]
    if side <= 0:
        return 0, 0, w, h
    x0, y0 = int(round(spot.u - side / 2)), int(round(spot.v - side / 2))
    return max(x0, 0), max(y0, 0), min(x0 + side, w), min(y0 + side, h)
