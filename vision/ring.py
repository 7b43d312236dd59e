"""A clipped white core inside a ring of the laser's colour: a laser spot, whatever its size (issue 41).

A phone photo of a sheet clips a laser spot of 2-3 mm: every channel is clipped over a core 5-30 px
in radius (the laser's channel first, the others through cross-talk and blooming, and the phone's
highlight processing whitens what is left), and the laser's colour survives only in a thin ring
around it, pink or orange for red, pale green for green. Printed grey or white dots, glints and
flashlights are white or grey discs too, but their edge is the colour of the surface around them:
white light adds light in the surface's own colour.

The test, on the photo's own encoded values (DN): around each white core (all channels over
:data:`~vision.features.LUMA_CLIP`) take the ring of pixels within :func:`ring_width` of it, cut into
:data:`SECTORS` angular sectors about the core's centre. In each sector, the laser channel's excess
over its neighbour channels (red: green, and blue less :data:`BLUE_SLACK`, since some cameras render
a red laser magenta; green: the brighter of red and blue), less the same excess of the surface there
(the local background, a plane fitted to the box's border), is the sector's colour. A core is
ringed when all but one sector show at least :data:`RING_MIN` DN of colour and the ring is not darker
than the surface in the laser's channel: a ring that surrounds the core, not a colour fringe on one
side (chromatic aberration, an object's edge). The spot's centre is the core's centroid (holes
filled): the symmetric centre of the clipped plateau, not the ring's brightest side.
"""

from __future__ import annotations

import cv2
import numpy as np

from lasercal.vision.features import CLIP, LUMA, LUMA_CLIP

SECTORS = 8  # angular sectors of the ring about the core's centre

# DN (8-bit scale) a sector's colour must reach over the surface's. Hand-set with the shared photos
# and the renderer in view, not fitted: held out nowhere (docs/vision.md names it).
RING_MIN = 15.0

# DN: a red laser's ring may be magenta (blue up to this much above red, Pi camera) but not bluer.
BLUE_SLACK = 40.0

# The ring's second-weakest sector holds at least this fraction of its second-strongest's colour.
RING_BALANCE = 0.25

# px: a white core smaller than this is left to the other rules (small cores: the spot's rim decides).
CORE_MIN = 50

# px: a core wider than this in radius is no laser spot of a sheet photo (a flashlight, a window);
# the rules for spots hundreds of px wide (vision.decide) judge it.
CORE_MAX = 60

# The laser channel's clipped plateau around a core covers at most this many times the core's area
# (twice its radius and more: a red-clipped ring 2-4 px wide around a core of 5 px, or a core that
# low exposure and weak cross-talk leave small).
PLATEAU_MAX = 16.0

# A ring band's neighbour channel rises over the surface by at most this fraction of its headroom.
RISE_MAX = 0.3

# DN: a ring band darker than the surface by more than this in the laser's channel is ink or an
# object's edge, not added light.
LIT_SLACK = 4.0


def ring_width(r_core: float) -> float:
    """How far beyond a core of radius ``r_core`` px its ring is sought, px: the colour may start a
    few px out (where the phone's highlight processing stops whitening) and the ring narrows to a few
    px far past clipping; the chroma planes (half resolution) blur it by ~2 px."""
    return float(np.clip(r_core, 8.0, 30.0))


def ringed_cores(plain: np.ndarray, base: np.ndarray, ch: int, full: float) -> list[tuple[np.ndarray, float]]:
    """The clipped cores of a box that a ring of the laser's colour surrounds.

    A core is clipped in the laser's channel and in its neighbour (:func:`_neighbours`): white, or
    yellow-white on yellow paper (whose blue the laser hardly lifts). Where no such core is ringed,
    the plateau clipped in the laser's channel alone is tried as the core (a spot whose cross-talk
    is too weak to clip the other channels), when it is brighter than the surface in the luma (red
    ink clips in red too, but takes light away).

    Parameters
    ----------
    plain : (h, w, 3) float array, the photo in the box, DN (BGR)
    base : (h, w, 3) float array, the surface under it (the local background), DN
    ch : int, the laser's channel (2 red, 1 green); full : float, full scale, DN

    Returns
    -------
    list of (core, colour): core (h, w) bool mask with its holes filled; colour, DN (8-bit scale), the
    second-weakest sector's colour (the ring's evidence), for each ringed core, largest first
    """
    scale = 255.0 / full
    nb = _neighbours(plain, ch)
    lase = (plain[..., ch] - nb) * scale
    colour = np.minimum(lase - (base[..., ch] - _neighbours(base, ch)) * scale, lase)
    if ch == 2:  # a red ring may be pink or magenta, never bluer than that
        blue = (plain[..., 0] - plain[..., 2] - np.maximum(base[..., 0] - base[..., 2], 0)) * scale
        colour = np.minimum(colour, BLUE_SLACK - blue + RING_MIN)
    lit = (plain[..., ch] - base[..., ch]) * scale
    # Laser light lifts the neighbour channel only by cross-talk; light of a warm (or greenish)
    # lamp lifts it by its own share, most where the laser's channel has just clipped.
    nb_base = _neighbours(base, ch)
    rise = (nb - nb_base) / np.maximum(full - nb_base, 0.02 * full)
    brighter = (plain - base) @ LUMA * scale
    plateau = plain[..., ch] >= CLIP * full
    _, plateaus, p_stats, _ = cv2.connectedComponentsWithStats(plateau.astype(np.uint8), connectivity=8)
    out = []
    for core in _cores(plateau & (nb >= LUMA_CLIP * full)):
        # The laser's channel clips a little beyond the core (the ring); a core deep inside a far
        # larger plateau is a speckle grain of a spot hundreds of px wide, or clipped paper.
        if p_stats[plateaus[core].max(), 4] > PLATEAU_MAX * core.sum():
            continue
        second = _ring_colour(core, colour, lit, rise)
        if second >= RING_MIN:
            out.append((core, second))
    for core in _cores(plateau):
        if any((core & c).any() for c, _ in out) or brighter[core].mean() < LIT_SLACK:
            continue
        second = _ring_colour(core, colour, lit, rise)
        if second >= RING_MIN:
            out.append((core, second))
    return out


def _cores(mask: np.ndarray) -> list[np.ndarray]:
    """The components of a mask from :data:`CORE_MIN` to :data:`CORE_MAX` in size, holes filled,
    largest first."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    keep = [i for i in np.argsort(-stats[1:, 4]) + 1 if CORE_MIN <= stats[i, 4] <= np.pi * CORE_MAX**2]
    return [_filled(labels == i) for i in keep]


def _ring_colour(core: np.ndarray, colour: np.ndarray, lit: np.ndarray, rise: np.ndarray) -> float:
    """The colour of the ring around a core, DN: its second-weakest sector's (-inf when the ring is
    not lit all around).

    The ring (out to :func:`ring_width`) is cut into :data:`SECTORS` about the core's centre and bands
    2 px wide; a band's colour is its mean, where it is lit (not darker than the surface: ink, a
    wire) and its neighbour channel has risen by at most :data:`RISE_MAX` of its headroom over the
    surface (a warm lamp's fringe lifts it far more); a sector's colour is its most coloured band's.
    The ring must be balanced: its second-weakest sector holds :data:`RING_BALANCE` of its
    second-strongest's colour.
    """
    h, w = core.shape
    r_core = float(np.sqrt(core.sum() / np.pi))
    dist = cv2.distanceTransform((~core).astype(np.uint8), cv2.DIST_L2, 5)
    ring = (dist > 0) & (dist <= ring_width(r_core))
    ys, xs = np.nonzero(core)
    yy, xx = np.mgrid[:h, :w]
    sector = (
        ((np.arctan2(yy - ys.mean(), xx - xs.mean()) + np.pi) / (2 * np.pi) * SECTORS).astype(int)
    ) % SECTORS
    nbands = int(ring_width(r_core) // 2) + 1
    key = (sector * nbands + (dist // 2).astype(int))[ring]
    count = np.bincount(key, minlength=SECTORS * nbands)
    mean_c = np.bincount(key, colour[ring], SECTORS * nbands) / np.maximum(count, 1)
    mean_l = np.bincount(key, lit[ring], SECTORS * nbands) / np.maximum(count, 1)
    mean_r = np.bincount(key, rise[ring], SECTORS * nbands) / np.maximum(count, 1)
    ok = (count >= 3) & (mean_l >= -LIT_SLACK) & (mean_r <= RISE_MAX)
    per = np.where(ok, mean_c, -np.inf).reshape(SECTORS, nbands).max(axis=1)
    seen = count.reshape(SECTORS, nbands).sum(axis=1) >= 3
    if seen.sum() < SECTORS - 2 or not np.isfinite(per[seen]).all():
        return -np.inf
    # A sector the box's edge cuts off says nothing either way.
    ranked = np.sort(per[seen])
    second, strong = float(ranked[1]), float(ranked[-2])
    # Light from a laser's own core falls off all around it; a white glint or disc in another spot's
    # halo sits on a slope of laser light, coloured on that spot's side only.
    return second if second >= RING_BALANCE * strong else -np.inf


def core_centre(core: np.ndarray) -> tuple[float, float, float]:
    """The centre (u, v) of a filled core in its box, px, and its sigma, px: the quantisation of a
    disc's outline (each of its ~2 pi r edge pixels is in or out, variance 1/12, at a lever
    r cos(theta): var = 1 / (12 pi r) for a disc of r px)."""
    m = cv2.moments(core.astype(np.uint8), binaryImage=True)
    r = np.sqrt(m["m00"] / np.pi)
    return m["m10"] / m["m00"], m["m01"] / m["m00"], float(1 / np.sqrt(12 * np.pi * r))


def _neighbours(img: np.ndarray, ch: int) -> np.ndarray:
    """The channel a laser's colour is weighed against: green for red (blue may rise with red, see
    :data:`BLUE_SLACK`), the brighter of red and blue for green."""
    return img[..., 1] if ch == 2 else np.maximum(img[..., 0], img[..., 2])


def _filled(mask: np.ndarray) -> np.ndarray:
    """A blob with its holes filled (speckle and JPEG leave dark specks in a clipped core)."""
    m = mask.astype(np.uint8)
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    out = np.zeros_like(m)
    cv2.drawContours(out, contours, -1, 1, thickness=cv2.FILLED)
    return out.astype(bool)
