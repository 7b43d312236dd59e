"""Issue 55: spots that clip so far their colour is gone, and clipped cores whose pixels lean.

:func:`white_cores`, :func:`counted` -- a spot exposed so far past clipping that its colour is gone
(highlight desaturation and blooming whiten the laser's neighbours) is a white clipped core with a rim a
person still sees as coloured, and the brightest compact blob of the frame. Its rim's shift towards the
laser's hue is faint (measured 1.1-1.7 on the rendered ones, where white light measures up to ~1.06), so
its colour alone cannot tell it from a glare; being the only compact white blob of its size in the photo
can (:func:`vision.decide.bare_alone`, rule "bare"). Where the photo holds several alike, each is refused
("several") with the reason.

:func:`rim_centre` -- the centre of a clipped core from the rim of its saturation: the clipped region,
its holes filled, opened by a disc of a part of its minor semi-axis (a flare streak, a glint or a
lobe of speckle joined to one side is thinner than the core and goes; the core's own outline stays),
then the centre of the ellipse fitted to the outline left. The mean of the clipped pixels leans
towards whatever joins the core on one side; the rim of the round part does not.

:func:`lopsided` -- what a laser spot is: a beam's light is point-symmetric about its centre (a
Gaussian, an ellipse, a clipped plateau: each the same turned half round), so its light, turned half
round about its centre, lands on itself. A glow along a lit edge (cut by a dark object on one side) or a
core a flare streak leans on does not. :attr:`~vision.decide.DecisionRule.lopsided_max` refuses such a
candidate among several (:func:`vision.detect._point_symmetric`); :attr:`~vision.decide.DecisionRule.lean_min`
centres a clipped core that lopsided on the rim of its saturation (:func:`vision.detect._rim_centred`).
"""

from __future__ import annotations

import cv2
import numpy as np

from lasercal.vision.ring import _filled

# The opening's disc, a share of the clipped core's minor semi-axis: a tail or lobe narrower than this
# share of the core goes, an ellipse of any aspect stays.
OPEN_SHARE = 0.6
# px: a precise fit this far from the rim's centre leans (vision.detect._rim_centred), where the spot's
# light is also lopsided (DecisionRule.lean_min). Alone (no lopsidedness asked), at 0.75 px and still at
# 1.5 px, it moved the phone sweep's clipped red spots (their red clip edge ragged by speckle and the
# 4:2:0 JPEG) from 0.02-0.05 to 0.13-0.21 px RMS at 3x and 30x.
RIM_STRAY = 0.75
# The opening must take at least this share of the clipped core for the core to lean: a round or
# elliptical core loses only its outline's jaggies (and a 4:2:0 JPEG's blocky red), and is left to the fit.
LEAN_MIN = 0.08
RIM_MIN_PX = 40  # clipped cores smaller than this are centred well enough by the precise fit
RIM_MAX_PX = 5000  # px (a core of r ~40 px): larger ones are spots hundreds of px wide, measured shrunk


def rim_centre(clipped: np.ndarray, at: tuple[float, float]) -> tuple[float, float] | None:
    """The centre (u, v) px, in the mask's box, of the clipped core nearest ``at``, from the rim of its
    saturation (see the module); None when there is no clipped core of :data:`RIM_MIN_PX` px there, or
    when it does not lean (the opening takes less than :data:`LEAN_MIN` of it).

    Parameters
    ----------
    clipped : (h, w) bool, the pixels clipped in the laser's channel
    at : (u, v) px, where the spot is (its centroid): the core is the clipped region holding it, or the
        nearest one
    """
    n, lab, stats, cents = cv2.connectedComponentsWithStats(clipped.astype(np.uint8), connectivity=8)
    if n <= 1:
        return None
    ix, iy = int(round(at[0])), int(round(at[1]))
    inside = lab[iy, ix] if 0 <= iy < lab.shape[0] and 0 <= ix < lab.shape[1] else 0
    k = inside or 1 + int(np.argmin(np.hypot(cents[1:, 0] - at[0], cents[1:, 1] - at[1])))
    if stats[k, cv2.CC_STAT_AREA] < RIM_MIN_PX:
        return None
    core = _filled(lab == k)
    m = cv2.moments(core.astype(np.uint8), binaryImage=True)
    a, b, c = m["mu20"] / m["m00"], m["mu11"] / m["m00"], m["mu02"] / m["m00"]
    minor = 2 * np.sqrt(max((a + c) / 2 - np.sqrt(((a - c) / 2) ** 2 + b**2), 1 / 12))
    r = max(1, int(round(OPEN_SHARE * minor)))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    opened = cv2.morphologyEx(core.astype(np.uint8), cv2.MORPH_OPEN, disc)
    n2, lab2, stats2, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    if n2 <= 1:
        return None
    part = (lab2 == 1 + int(np.argmax(stats2[1:, cv2.CC_STAT_AREA]))).astype(np.uint8)
    if part.sum() > (1 - LEAN_MIN) * core.sum():  # nothing joins the core: the precise fit stands
        return None
    contours, _ = cv2.findContours(part, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = max(contours, key=len).reshape(-1, 2).astype(np.float32)
    if len(pts) < 6:
        return None
    return _robust_ellipse(pts)


def _robust_ellipse(pts: np.ndarray, rounds: int = 3) -> tuple[float, float]:
    """The centre of the ellipse fitted to outline points, refitted without the points that stand out
    of it (a bump a lobe left at the core's edge): those beyond 1 + 2 x the points' median absolute
    deviation of the normalised radius."""
    keep = pts
    (u, v), axes, ang = cv2.fitEllipse(keep)
    for _ in range(rounds):
        t = np.radians(ang)
        d = pts - (u, v)
        x = (d[:, 0] * np.cos(t) + d[:, 1] * np.sin(t)) / max(axes[0] / 2, 1e-3)
        y = (-d[:, 0] * np.sin(t) + d[:, 1] * np.cos(t)) / max(axes[1] / 2, 1e-3)
        rho = np.hypot(x, y)
        mad = float(np.median(np.abs(rho - np.median(rho))))
        sel = pts[rho <= np.median(rho) + max(3 * mad, 0.02)]
        if len(sel) < 6 or len(sel) == len(keep):
            break
        keep = sel
        (u, v), axes, ang = cv2.fitEllipse(keep)
    return float(u), float(v)


# A white blob is a laser core's size from a lens-blurred spot (MIN_BLOB) up to a core of ~40 px radius: a
# flashlight's hotspot or a window is larger. Another blob is "alike" when it has a quarter of the area.
BARE_MIN_PX = 20
BARE_MAX_PX = 5000
PEER_SHARE = 0.25


def white_cores(img: np.ndarray) -> list[tuple[int, np.ndarray, tuple]]:
    """The photo's compact white clipped blobs of a laser core's size: (area px, centre (u, v) px, box
    (x0, y0, x1, y1)) each (white: every channel >= LUMA_CLIP of full scale; compact: see
    :func:`vision.features.compact_blob`)."""
    from lasercal.vision.features import LUMA_CLIP, compact_blob
    from lasercal.vision.images import all_at_least, full_scale

    white = all_at_least(img, LUMA_CLIP * full_scale(img)).astype(np.uint8)
    n, lab, stats, cents = cv2.connectedComponentsWithStats(white, connectivity=8)
    out = []
    for i in range(1, n):
        x, y, w, h, a = stats[i]
        if BARE_MIN_PX <= a <= BARE_MAX_PX and compact_blob(lab[y : y + h, x : x + w] == i):
            out.append((int(a), cents[i], (int(x), int(y), int(x + w), int(y + h))))
    return out


def counted(s, cores: list):
    """A spot (:class:`~vision.spot.Spot`) whose position lies on one of ``cores`` (:func:`white_cores`),
    with :attr:`~vision.spot.Evidence.bare` set to how many of them are alike (its own included); as it
    was when it lies on none."""
    from dataclasses import replace

    ev = s.evidence
    if ev is None or not ev.white_px:
        return s
    mine = [c for c in cores if c[2][0] - 2 <= s.u <= c[2][2] + 1 and c[2][1] - 2 <= s.v <= c[2][3] + 1]
    if not mine:
        return s
    area = max(c[0] for c in mine)
    alike = sum(c[0] >= PEER_SHARE * area for c in cores)
    return replace(s, evidence=replace(ev, bare=int(alike)))


# The window of :func:`lopsided`: 1.5 x the blob's radius (the core and its flanks), 4-40 px.
LOPSIDED_REACH = (1.5, 4.0, 40.0)


def lopsided(img: np.ndarray, channel: int | None, u: float, v: float, area: float) -> float:
    """How far a spot's light is from point-symmetric about its centre: over a disc of
    :data:`LOPSIDED_REACH` about (u, v), the laser channel's rise E over its 5th percentile there, and
    sum |E(x) - E(2c - x)| / sum (E(x) + E(2c - x)) (0: the light turned half round lands on itself;
    1: all of it on one side). Bilinear, the photo's edge replicated.

    Parameters
    ----------
    img : (h, w, 3) or (h, w) photo
    channel : int or None, the laser's channel (None for a grey photo)
    u, v : px, the spot's centre
    area : px, its blob's area
    """
    ch = (img if img.ndim == 2 or channel is None else img[..., channel]).astype(np.float32)
    if ch.ndim == 3:
        ch = ch.mean(axis=2)
    k, lo, hi = LOPSIDED_REACH
    r = float(np.clip(k * np.sqrt(area / np.pi), lo, hi))
    pad = int(np.ceil(r)) + 2
    x0, y0 = int(round(u)) - pad, int(round(v)) - pad
    padded = cv2.copyMakeBorder(ch, pad + 2, pad + 2, pad + 2, pad + 2, cv2.BORDER_REPLICATE)
    patch = padded[y0 + pad + 2 : y0 + 3 * pad + 3, x0 + pad + 2 : x0 + 3 * pad + 3]
    cu, cv_ = u - x0, v - y0
    turn = np.float32([[-1, 0, 2 * cu], [0, -1, 2 * cv_]])
    turned = cv2.warpAffine(
        patch, turn, patch.shape[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    yy, xx = np.mgrid[: patch.shape[0], : patch.shape[1]]
    disc = np.hypot(xx - cu, yy - cv_) <= r
    floor = float(np.percentile(patch[disc], 5))
    e, et = np.maximum(patch[disc] - floor, 0), np.maximum(turned[disc] - floor, 0)
    return float(np.abs(e - et).sum() / max(float((e + et).sum()), 1e-6))
