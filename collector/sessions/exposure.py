"""The exposure of a camera the tool controls, set once at a session's start (``capture --camera``,
``validate``): lowered until the laser spot's core no longer clips, or to the least clipping that keeps the
photo readable (the sheet's markers found, the spot measured).

A clipped core hides the spot's profile: only the plateau's edge and the flanks are left to measure
(:mod:`vision.exposure`). The camera is driven through OpenCV's properties (``CAP_PROP_AUTO_EXPOSURE``
to manual, then ``CAP_PROP_EXPOSURE``), each read back: many drivers accept a value and ignore it. A
device that does not let its exposure be set is said so on stderr, and the session goes on as before.
The fake cameras take the same properties (:class:`FakeExposure`).
"""

from __future__ import annotations

import sys

import cv2
import numpy as np

from lasercal.collector.hardware.cameras import AUTO_OFF
from lasercal.vision.errors import VisionError

MAX_HALVINGS = 8  # 256x darker at most: past that the paper is black


def clipped_px(img: np.ndarray) -> int | None:
    """Pixels of the photo's spot clipped in the laser's channel (the most clipped spot,
    :func:`vision.exposure.exposure_advice`), or None when no spot is found."""
    from lasercal.vision.detect import detect_spots
    from lasercal.vision.exposure import exposure_advice

    try:
        spots, _ = detect_spots(img, "exposure")
    except VisionError:
        return None
    advice = exposure_advice(spots)
    return 0 if advice is None else advice.clipped_px


def readable_by(measure):
    """A photo is readable when ``measure(img, name)`` finds the spot (and the markers, with a layout
    that has them); with no ``measure`` every photo is."""
    if measure is None:
        return lambda img: True

    def readable(img) -> bool:
        try:
            measure(img, "exposure")
        except VisionError:
            return False
        return True

    return readable


def darker(value: float) -> float:
    """Half the exposure: OpenCV's ``CAP_PROP_EXPOSURE`` is log2 seconds on DirectShow and MSMF (a
    negative number: one less), a linear time on V4L2 (100 us units: half)."""
    return value - 1.0 if value <= 0 else value / 2


def set_exposure(camera, value: float, was: float) -> float | None:
    """Ask for exposure ``value``; the one the device reads back, or None when it stayed at ``was`` or
    above (refused, or ignored: drivers round to their step, so only darker is checked)."""
    camera.set(cv2.CAP_PROP_EXPOSURE, value)
    back = camera.get(cv2.CAP_PROP_EXPOSURE)
    return float(back) if back < was else None


def manual_exposure(camera) -> float | None:
    """Switch the device's auto exposure off: its exposure then, or None when it does not allow it."""
    for v in AUTO_OFF:
        if camera.set(cv2.CAP_PROP_AUTO_EXPOSURE, v) and camera.get(cv2.CAP_PROP_AUTO_EXPOSURE) == v:
            return float(camera.get(cv2.CAP_PROP_EXPOSURE))
    return None


def settle_exposure(camera, readable=lambda img: True, out=sys.stderr, max_steps: int = MAX_HALVINGS):
    """The session's first photo, taken after the exposure was lowered so that the spot does not clip.

    With the laser on a point: a photo; while its spot clips (or, overexposed, is not found at all), the
    exposure halves and a new photo is taken; a readable photo followed by one that is not (markers lost,
    spot gone) ends it at the exposure before: the least clipping that keeps the photo readable. Nothing
    changes (and nothing is said) when the spot does not clip or the camera is not one the tool controls
    (``exposure_control`` false); when no exposure gives a readable photo, the first one is kept.

    Parameters
    ----------
    camera : with ``photo()``, ``get(prop)``, ``set(prop, value) -> bool`` (OpenCV's properties) and
        ``exposure_control``
    readable : callable(img) -> bool, the photo can be measured (:func:`readable_by`)
    out : text stream for the one line said (stderr)
    max_steps : int, halvings at most

    Returns
    -------
    (h, w, 3) uint8 array, the photo at the exposure settled on (the session's first)
    """
    img = camera.photo()
    if not getattr(camera, "exposure_control", False):
        return img
    clip = clipped_px(img)
    if clip == 0:
        return img
    value = manual_exposure(camera)
    if value is None:
        seen = "is not found" if clip is None else f"clips over {clip} px"
        out.write(
            f"camera {camera.name}: the spot {seen} and the device does not let its exposure be set "
            "(CAP_PROP_AUTO_EXPOSURE, CAP_PROP_EXPOSURE): lower it by hand if it is overexposed\n"
        )
        return img
    ok = clip is not None and readable(img)
    start = value
    best = (value, clip, img) if ok else None
    for _ in range(max_steps):
        new = set_exposure(camera, darker(value), value)
        if new is None:
            out.write(f"camera {camera.name}: exposure {darker(value):g} refused, kept {value:g}\n")
            break
        value = new
        shot = camera.photo()
        c = clipped_px(shot)
        if c is not None and readable(shot):
            best = (value, c, shot)
            if c == 0:
                break
        elif best is not None:  # readable before, no longer: too dark (the exposure before)
            break
    if best is None:  # no readable photo at any exposure tried (the spot hidden, or off the sheet)
        camera.set(cv2.CAP_PROP_EXPOSURE, start)
        out.write(
            f"camera {camera.name}: no readable spot at exposures {start:g} to {value:g}: kept {start:g}\n"
        )
        return img
    if best[0] != value:
        camera.set(cv2.CAP_PROP_EXPOSURE, best[0])
    was = "not found" if clip is None else f"clipped over {clip} px"
    out.write(f"camera {camera.name}: exposure {start:g} -> {best[0]:g}: the spot {was}, now {best[1]} px\n")
    return best[2]
