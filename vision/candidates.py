"""Stage 1 of spot detection: candidate regions that may hold a laser spot.

Coordinates are pixels in OpenCV's convention (pixel centres at integer coordinates, ``u`` right,
``v`` down); intensities are digital numbers (DN) of the photo.

On a 1/f-size block average (fast on 12-megapixel photos), the paper level (a tile percentile, so
black markers do not sink it) is removed from the laser's channel and from its *colour excess* (the
channel minus the brighter other one: ~0 on white paper, black ink and white glare alike). A region
brighter than the paper in the laser's channel is a candidate as a whole when a few of its pixels
are laser-coloured (the halo of a white core). The same on a coarse copy (~64 rows) finds spots too
wide for the tiles, and clipped white blobs are candidates too (the cores of spots far past
clipping). A search region (the sheet, when its markers are found) keeps the candidates inside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from lasercal.vision.features import LUMA_CLIP, _robust_sigma
from lasercal.vision.images import all_at_least, full_scale
from lasercal.vision.spot import CHANNEL

MAX_CANDIDATES = 50


@dataclass(frozen=True)
class Candidate:
    """A region that may hold a laser spot.

    Attributes
    ----------
    box : (x0, y0, x1, y1) ints, px, half-open, full resolution
    u, v : float, rough centre, px
    ring_only : bool, a core clipped in the laser's channel and its neighbour but not white (yellow
        paper): a spot only if a laser-coloured ring surrounds it (:mod:`vision.ring`)
    """

    box: tuple[int, int, int, int]
    u: float
    v: float
    ring_only: bool = False


def _channels(img: np.ndarray, ch: int) -> tuple[np.ndarray, np.ndarray]:
    """The laser's channel and its colour excess (the channel minus the brighter
    other one, clipped at 0); a grey image is both."""
    if img.ndim == 2:
        return img, img
    laser, a, b = (cv2.extractChannel(img, c) for c in (ch, *(c for c in range(3) if c != ch)))
    return laser, cv2.subtract(laser, cv2.max(a, b))


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
    search: np.ndarray | None = None,
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
    search : (n, 2) array or None, px: a polygon outside which candidates are dropped (the sheet)

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
    cores = _core_candidates(small, f, (h, w), CHANNEL[colour]) if src.ndim == 3 and reference is None else []
    cores = [c for c in cores if not any(_inside(c, o) for o in white + fine)]
    found = coarse + white + fine + cores  # the few large ones first: fine ones abound
    if search is not None:
        poly = np.asarray(search, np.float32).reshape(-1, 1, 2)
        found = [c for c in found if cv2.pointPolygonTest(poly, (c.u, c.v), False) >= 0]
    return found[:MAX_CANDIDATES]


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
    white = all_at_least(small, LUMA_CLIP * full_scale(small))
    return _boxes(white, white.astype(np.float32), f, shape, 2)


def _core_candidates(small: np.ndarray, f: int, shape: tuple[int, int], ch: int) -> list[Candidate]:
    """Cores clipped in the laser's channel and its neighbour but not white: a spot on yellow paper,
    whose blue the laser hardly lifts. Judged by their ring only (:mod:`vision.ring`)."""
    top = LUMA_CLIP * full_scale(small)
    nb = small[..., 1] if ch == 2 else np.maximum(small[..., 0], small[..., 2])
    core = (small[..., ch] >= top) & (nb >= top) & ~all_at_least(small, top)
    found = _boxes(core, core.astype(np.float32), f, shape, 2)
    return [Candidate(c.box, c.u, c.v, ring_only=True) for c in found]


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
