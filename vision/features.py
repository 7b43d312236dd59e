"""Stage 2 of spot detection: what a candidate looks like, measured in ways that transfer between
cameras (see :class:`~vision.spot.Evidence`).

Each candidate's box gets a local background (a plane fitted robustly to the box's border) and its
noise; from them the spot's blob, its excess in the laser's channel and in the luma (laser light adds
light), the colour its rim adds against the paper under it (:func:`_rim_shift`, in linear light), the
clipped and white pixels of its core, and its shape (:func:`_ellipse_fit`).
"""

from __future__ import annotations

import cv2
import numpy as np

from lasercal.vision.images import all_at_least
from lasercal.vision.spot import Evidence

MIN_FILL = 0.8  # area over the moment ellipse: 1 for an ellipse, ~0.95 cut, >= 0.91 for real spots
MAX_ASPECT = 2.5  # a beam 66 deg off the normal: far past any pose that aims a laser at a sheet

LUMA = np.array([0.114, 0.587, 0.299])  # BGR weights of JPEG's luma (ITU-R BT.601)


CR = np.array([-0.0813, -0.4187, 0.5])  # BGR weights of JPEG's red chroma difference (Cr)


CLIP = 0.985  # a recorded value at or above this fraction of full scale is clipped


LUMA_CLIP = 0.97  # the same for the luma: JPEG ringing wobbles a white core by a few DN


HALO_CAP = 20.0


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


def _robust_sigma(x: np.ndarray) -> float:
    x = x.ravel()[:: max(1, x.size // 50_000)]  # a sample is plenty for a noise level
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


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
    # Trimmed least squares (start from the border's median, then refit on the better-fitting 60 %
    # of the border, four times): where the border crosses an edge between two surfaces (a spot near
    # a dark panel) a plane through both would be neither, and the spread about it would pass for
    # noise; the trimmed fit settles on the surface that holds most of the border, shading and all.
    coef = np.zeros((3, c))
    coef[0] = np.median(vals, 0)
    n_keep = max(int(0.6 * len(vals)), min(8, len(vals)))
    for _ in range(4):
        dev = np.abs(vals - A @ coef).max(1)
        keep = np.argsort(dev)[:n_keep]
        coef, *_ = np.linalg.lstsq(A[keep], vals[keep], rcond=None)
    res = vals[keep] - A[keep] @ coef
    for _ in range(2):  # take back the border pixels the trimmed plane explains (ink, spots stay out)
        mad = 1.4826 * np.median(np.abs(res - np.median(res, 0)), 0) + 1e-6
        inl = np.all(np.abs(vals - A @ coef) < 3 * mad + 1, 1)
        if inl.sum() < 8:
            break
        coef, *_ = np.linalg.lstsq(A[inl], vals[inl], rcond=None)
        res = vals[inl] - A[inl] @ coef
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


def _touches_border(sig: np.ndarray, noise: float, peak: float) -> bool:
    """Whether the spot's own region (its laser-coloured light ``sig`` above a tenth of its peak and 3
    sigma, connected to its peak) reaches the box's border: only then is the box too small. Other
    lights crossing the border are no reason to grow (a box grown over them would hold the scene).

    Parameters
    ----------
    sig : (h, w) array, the laser channel's excess over the other channels' (grey: the excess), DN
    noise : float, DN; peak : float, the largest of ``sig``, DN
    """
    sm = cv2.GaussianBlur(sig, (0, 0), 1.0)  # single noisy border pixels are no reason to grow
    above = (sm > max(3 * noise, 0.1 * peak)).astype(np.uint8)
    _, labels = cv2.connectedComponents(above, connectivity=8)
    own = labels[np.unravel_index(np.argmax(sm), sm.shape)]
    if own == 0:
        return False
    rim = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    return bool((rim == own).any())


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


def _label_at(labels: np.ndarray, x: float, y: float) -> int:
    """The label under a point of the box (0 outside the box or on the background)."""
    ix, iy = int(round(x)), int(round(y))
    if 0 <= iy < labels.shape[0] and 0 <= ix < labels.shape[1]:
        return int(labels[iy, ix])
    return 0


def _others_max(a: np.ndarray, ch: int) -> np.ndarray:
    """The larger of the two channels of ``a`` (h, w, 3) other than ``ch``, per pixel: what
    ``np.max(np.delete(a, ch, axis=2), axis=2)`` gives, without its copy of the box (14 ms of a
    half-megapixel box's 15)."""
    lo, hi = (k for k in range(3) if k != ch)
    return np.maximum(a[..., lo], a[..., hi])


def _box_array(memo: dict | None, key, make):
    """``make()``, made once per candidate box: ``memo`` (the box's, see :class:`vision.decide._Box`) keeps
    what every light measured in the box would make alike (a photo's large box can hold dozens of lights);
    None keeps nothing."""
    if memo is None:
        return make()
    if key not in memo:
        memo[key] = make()
    return memo[key]


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
    ink: np.ndarray | None = None,
    memo: dict | None = None,
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
    ink : (h, w) bool array or None, printed or dark pixels in the box (see :func:`_laser_light`)
    memo : dict or None, the box's arrays for its other lights (:func:`_box_array`)
    """
    area = 0 if blob is None else int(blob.sum())
    grey = plain.shape[2] == 1
    clipped = white = 0
    halo = None
    light = peak_d
    level = 0.0 if blob is None else float(plain[..., ch][blob].max()) / full
    if blob is not None:
        clipped = int((plain[..., ch][blob] >= CLIP * full).sum())
        white_px = _box_array(memo, "white", lambda: all_at_least(plain, LUMA_CLIP * full))
        white = int(white_px[blob].sum())
        if not grey:
            rise = _box_array(memo, "luma", lambda: delta @ LUMA)  # the luma's rise over the paper
            luma = _box_array(memo, ("luma", 1.0), lambda: cv2.GaussianBlur(rise, (0, 0), 1.0))
            light = float(luma[blob].max())
            # The halo: pixels of the spot and just around it not clipped in all channels, with a
            # clear excess. Summed over the halo: a clipped spot's colour may survive in a rim only
            # one or two pixels wide, which JPEG's half-resolution colour dilutes further.
            lase, other = delta[..., ch], _box_array(memo, "other", lambda: _others_max(delta, ch))
            ring = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~white_px
            ring &= lase > max(0.1 * peak_d, 4 * noise[ch])
            if ring.sum() >= 3:
                total = float(lase[ring].sum())
                halo = total / max(float(np.maximum(other[ring], 0).sum()), total / HALO_CAP)
            else:
                halo = 1.0  # all white: nothing says laser
    rim = paper = shift = surround = side = None
    reach = 0.0
    flux = 0.0
    if blob is not None and gamma is not None:
        base = _box_array(memo, "base", lambda: plain - delta)
        flux = float(
            (_linear(plain[..., ch][blob], full, gamma) - _linear(base[..., ch][blob], full, gamma)).sum()
        )
    if blob is not None and not grey and gamma is not None:
        rim, paper, _ = _rim_shift(plain, base, blob, ch, full, gamma, max(0.03 * peak_d, 4 * noise[ch]))
        shift = rim / max(1.0, paper)
        surround = _box_array(memo, ("surround", gamma), lambda: _surround(base, ch, full, gamma))
        side, reach = _laser_light(delta, blob, ch, noise, ink, memo)
    lit = min(np.log(max(peak_d, 1e-6) / need), np.log(max(light, 1e-6) / _light_need(noise, full)))
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
        0.0,
        rim,
        paper,
        shift,
        None,
        flux,
        surround=surround,
        lit=float(lit),
        side=side,
        reach=float(reach),
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


# The laser-coloured light of a spot reaches out to where it falls below this fraction of its peak (and
# 4 sigma of the paper): its halo, in which whatever else looks lit by a laser is that spot's light.
HALO_FRACTION = 0.05


def _laser_colour(delta: np.ndarray, ch: int) -> np.ndarray:
    """The laser-coloured light a box adds over its paper, DN: the light added in the laser's channel
    less that added in its neighbours (:data:`NEIGHBOURS`, the larger), smoothed over 1 px (speckle,
    demosaicing). Only added light counts: red ink, which takes green away, adds none."""
    others = np.max(np.maximum(delta[..., list(NEIGHBOURS[ch])], 0), axis=2)
    return cv2.GaussianBlur(np.maximum(delta[..., ch], 0) - others, (0, 0), 1.0)


def _laser_light(
    delta: np.ndarray,
    blob: np.ndarray,
    ch: int,
    noise: np.ndarray,
    ink: np.ndarray | None = None,
    memo: dict | None = None,
) -> tuple[float, float]:
    """How one-sided a candidate's laser-coloured light is about it, and how far that light reaches.

    A laser's light falls off all around its spot: its halo is centred on it. A grey disc, a glint or
    a lighter patch lit by *another* spot's halo, or a lamp's core with red light on one side (an
    object's edge hides the rest), has laser-coloured light on one side of it only. ``side`` is the
    light's dipole about the centre of the blob's brightest part (its top tenth in the luma smoothed
    over a third of its radius: a spot's clipped core, a lamp, a glint, not a speckle grain; the whole
    blob's centre where ink lies in it, which darkens the middle of a spot on a mark), over the
    pixels within a ring width of the blob whose mirror images lie in the box too (so that an edge of
    the box or of the photo does not tilt it): |sum w (p - c)| / sum w |p - c|, w the laser-coloured
    light; 0 for light centred on it, 1 for light all on one side. Where ink (or a dark object) lies
    in the window, only pairs of pixels clear of it count for the dipole, and the share of the light
    whose mirror image falls on it counts on its own: a thin printed line through a spot hides the
    light on both sides alike, an object's edge through a lamp hides one side.

    ``reach`` is the largest distance from that centre of the region of laser-coloured light around the
    blob (above :data:`HALO_FRACTION` of its peak and 4 sigma): its halo.

    Returns
    -------
    side : float in [0, 1]; reach : float, px
    """
    h, w = blob.shape
    lase = _box_array(memo, "lase", lambda: _laser_colour(delta, ch))
    r_blob = np.sqrt(blob.sum() / np.pi)
    # Smoothed over a third of the spot's radius: speckle grains do not move its brightest part.
    smooth = max(1.0, r_blob / 3)  # the box's (a small blob's) or the blob's own
    rise = _box_array(memo, "luma", lambda: delta @ LUMA)  # the luma's rise over the paper
    if smooth == 1.0:  # the box's, as _evidence smooths it
        luma = _box_array(memo, ("luma", 1.0), lambda: cv2.GaussianBlur(rise, (0, 0), 1.0))
    else:
        luma = cv2.GaussianBlur(rise, (0, 0), smooth)
    top = float(luma[blob].max())
    brightest = blob & (luma >= top - 0.1 * abs(top))
    if (
        ink is not None and (ink & blob).any()
    ):  # ink darkens the spot's middle: its blob, bridged over the ink
        brightest = blob
    m = cv2.moments(brightest.astype(np.uint8), binaryImage=True)
    cx, cy = m["m10"] / m["m00"], m["m01"] / m["m00"]
    dist = cv2.distanceTransform((~blob).astype(np.uint8), cv2.DIST_L2, 5)
    yy, xx = _box_array(memo, "grid", lambda: np.mgrid[:h, :w].astype(np.float32))
    mirrored = (2 * cx - xx >= 0) & (2 * cx - xx <= w - 1) & (2 * cy - yy >= 0) & (2 * cy - yy <= h - 1)
    near = (dist <= float(np.clip(r_blob, 8.0, 30.0))) & mirrored
    light = np.where(near, np.maximum(lase, 0.0), 0.0)
    hidden = 0.0
    if ink is not None:
        mirror = cv2.remap(ink.astype(np.uint8), 2 * cx - xx, 2 * cy - yy, cv2.INTER_NEAREST).astype(bool)
        total = float(light[~ink].sum())
        # Only a dark region as wide as the spot's radius hides one side (an object's edge); a printed
        # line, however near the centre, is thinner (MuJoCo's validation spot on a cross's line read 0.75)
        wide = float(cv2.distanceTransform((ink & near).astype(np.uint8), cv2.DIST_L2, 5).max()) > r_blob / 2
        if wide and total > 0:
            hidden = float(light[~ink & mirror].sum()) / total
        light = np.where(ink | mirror, 0.0, light)
    dx, dy = xx - cx, yy - cy
    lever = float((light * np.hypot(dx, dy)).sum())
    side = float(np.hypot((light * dx).sum(), (light * dy).sum()) / lever) if lever > 0 else 0.0
    side = max(side, hidden)
    nb = max(NEIGHBOURS[ch], key=lambda o: noise[o])
    peak = float(lase[cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)].max())
    halo = (lase > max(HALO_FRACTION * peak, 4 * float(np.hypot(noise[ch], noise[nb])))).astype(np.uint8)
    n, labels = cv2.connectedComponents(halo | blob.astype(np.uint8), connectivity=8)
    own = np.unique(labels[blob])
    region = np.isin(labels, own[own > 0])
    reach = float(np.hypot(dx[region], dy[region]).max()) if region.any() else r_blob
    return side, reach


def _light_need(noise: np.ndarray, full: float) -> float:
    """The rise of the luma a spot needs, DN: 4 sigma of the paper's luma noise, at least 1.5 % of
    full scale (colour correction leaves a dim red spot only ~1/3 of its red rise in the luma)."""
    return max(4 * float(noise @ LUMA) if noise.size == 3 else 4 * float(noise[0]), 0.015 * full)


def compact_blob(blob: np.ndarray) -> bool:
    """Whether a blob is a compact ellipse (see :data:`MIN_FILL` and :data:`MAX_ASPECT`): what a beam on a
    plane makes, where a wire, a frame or an edge does not."""
    fill, aspect = _ellipse_fit(blob)
    return fill >= MIN_FILL and aspect <= MAX_ASPECT
