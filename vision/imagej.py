"""An emulation of measuring a laser spot by hand in ImageJ (thesis Section 4.3).

What a person does: draw a box around the spot (or none: the whole photo), convert
the RGB photo to 8-bit grey, Image > Adjust > Threshold with the ``Default``
method (ImageJ's modified IsoData) or ``Otsu`` and "Dark background", then
Analyze Particles / Measure with ``Centroid`` (mean of the particle's pixel
coordinates) or ``Center of Mass`` (grey-weighted mean, no background
subtraction).

ImageJ facts kept here: RGB -> grey is the unweighted (R + G + B) / 3, rounded;
the Default threshold ignores the levels 0 and 255 and caps the histogram's mode;
foreground is grey > level; particles are 8-connected; ImageJ reports positions
+0.5 px from OpenCV's convention (its pixel (0, 0) spans 0..1). Here positions
are returned in OpenCV's convention, pixels; the caller shifts them for output.
"""

from __future__ import annotations

import cv2
import numpy as np

from lasercal.vision.errors import VisionError
from lasercal.vision.images import full_scale
from lasercal.vision.spot import CHANNEL, Spot


def default_threshold(hist: np.ndarray) -> int:
    """ImageJ's ``Default`` threshold (modified IsoData) of a 256-bin histogram.

    Parameters
    ----------
    hist : (256,) int array

    Returns
    -------
    int, the level; foreground is grey > level
    """
    h = np.asarray(hist, float).copy()
    mode = int(np.argmax(h))
    second = np.max(np.delete(h, mode))
    if h[mode] > 2 * second and second > 0:
        h[mode] = int(second * 1.5)  # a huge background mode would swamp the means
    h[0] = h[255] = 0  # erased and saturated areas are ignored
    nz = np.nonzero(h)[0]
    if len(nz) == 0 or nz[0] >= nz[-1]:
        return 128
    lo, hi = nz[0], nz[-1]
    levels = np.arange(256, dtype=float)
    c_n, c_s = np.cumsum(h), np.cumsum(h * levels)
    result = 0.0
    for i in range(lo, hi):  # move the split up until it passes the mean of the two class means
        below = c_s[i] / c_n[i]
        above = (c_s[hi] - c_s[i]) / (c_n[hi] - c_n[i])
        result = (below + above) / 2
        if not (i + 2 <= result and i + 1 < hi - 1):
            break
    return int(np.floor(result + 0.5))


def otsu_threshold(hist: np.ndarray) -> int:
    """Otsu's threshold of a 256-bin histogram (maximal between-class variance).

    Returns
    -------
    int, the level; foreground is grey > level
    """
    h = np.asarray(hist, float)
    levels = np.arange(256)
    w0 = np.cumsum(h)
    m0 = np.cumsum(h * levels)
    w1 = w0[-1] - w0
    with np.errstate(divide="ignore", invalid="ignore"):
        between = (m0[-1] * w0 - m0 * w0[-1]) ** 2 / (w0 * w1)
    between[~np.isfinite(between)] = -1
    return int(np.argmax(between))


def gray8(img: np.ndarray) -> np.ndarray:
    """ImageJ's RGB -> 8-bit conversion: unweighted mean of B, G, R, rounded."""
    g = img.astype(np.float32) if img.ndim == 2 else img.astype(np.float32).mean(-1)
    return np.floor(g * (255 / full_scale(img)) + 0.5).astype(np.uint8)


def measure(
    img: np.ndarray,
    box: tuple[int, int, int, int],
    mode: str = "centroid",
    threshold: str = "default",
    colour: str = "red",
) -> Spot:
    """Measure the spot in ``box`` as a person would in ImageJ.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array
    box : (x0, y0, x1, y1), px, half-open: the drawn selection
    mode : "centroid" or "com" (Center of Mass)
    threshold : "default" or "otsu"
    colour : laser colour, only to report the peak of its channel

    Returns
    -------
    Spot with u, v in OpenCV's convention and no uncertainty

    Raises
    ------
    VisionError
        The threshold does not isolate a spot (the particle touches the selection's
        border or covers most of it): in ImageJ the person would see a failure.
    """
    x0, y0, x1, y1 = box
    crop = img[y0:y1, x0:x1]
    g = gray8(crop)
    hist = np.bincount(g.ravel(), minlength=256)
    level = default_threshold(hist) if threshold == "default" else otsu_threshold(hist)
    fg = g > level
    n, labels, stats, _ = cv2.connectedComponentsWithStats(fg.astype(np.uint8), connectivity=8)
    if n <= 1:
        raise VisionError(f"{threshold} threshold {level}: nothing above it")
    i = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x, y, bw, bh, area = stats[i]
    # A whole-photo selection may hold the photo's border; a drawn box must isolate the spot.
    touches = (x == 0 or y == 0 or x + bw == g.shape[1] or y + bh == g.shape[0]) and (
        x1 - x0,
        y1 - y0,
    ) != img.shape[1::-1]
    if touches or area > 0.25 * g.size:
        raise VisionError(
            f"{threshold} threshold {level} does not isolate the spot "
            f"(particle of {area} px{' touching the selection' if touches else ''})"
        )
    yy, xx = np.nonzero(labels == i)
    if mode == "com":
        wts = g[yy, xx].astype(float)
        u, v = (xx * wts).sum() / wts.sum(), (yy * wts).sum() / wts.sum()
    elif mode == "centroid":
        u, v = xx.mean(), yy.mean()
    else:
        raise VisionError(f"unknown ImageJ measurement '{mode}' (centroid or com)")
    ch = crop[..., CHANNEL[colour]] if crop.ndim == 3 else crop
    vals = ch[yy, xx]
    return Spot(
        float(u + x0),
        float(v + y0),
        None,
        None,
        float(vals.max()),
        bool((vals >= 0.985 * full_scale(img)).any()),
        int(area),
    )
