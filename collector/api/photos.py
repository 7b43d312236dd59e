"""``lasercal.spots``: the laser spots of photos, in pixels and on the plane (``lasercal spots``).

A thin door to :mod:`lasercal.vision` (which stands alone): each photo is read, its spots found and
measured to sub-pixel precision (:func:`~lasercal.vision.measure.measure_file`), and mapped to mm on the
plane through the layout's markers when it has some.
"""

from __future__ import annotations

from pathlib import Path


def spots(photos, *, layout=None, camera=None, reference=None, expect: int | None = 1, **options) -> list:
    """Measure the laser spots of photos; a photo that cannot be measured says why (it never raises).

    Parameters
    ----------
    photos : str, Path or (h, w[, 3]) uint8/uint16 array, or a sequence of them (an array is named
        ``photo N`` in messages)
    layout : str or Path, a layout YAML with ``markers`` (ArUco/ChArUco): spots in mm on the plane too
    camera : str or Path, a camera YAML (``lasercal camera-calibrate``): lens distortion undone first
    reference : str, Path or array, a laser-off photo of the same view
    expect : int or None, spots per photo (None: any number)
    options : the other fields of :class:`lasercal.vision.measure.Options` (``method='precise'`` or
        ``'imagej'``, ``colour``, ``gamma``, ``channel``, ``imagej_mode``, ``imagej_threshold``,
        ``imagej_box``)

    Returns
    -------
    list of PhotoResult, one per photo: ``spots`` (u, v px in OpenCV's convention, x, y mm with markers,
    and their standard deviations), ``warnings``, ``plane`` (the markers' fit), ``error`` (why a photo was
    lost, else None); ``to_dict(method)`` gives the ``lasercal spots --json`` entry

    Raises
    ------
    VisionError
        An unreadable layout, camera or reference file.
    """
    import numpy as np

    from lasercal.vision.camera import load_camera
    from lasercal.vision.errors import VisionError
    from lasercal.vision.images import read_image
    from lasercal.vision.measure import Options, PhotoResult, measure_file, measure_photo
    from lasercal.vision.plane import load_markers

    opts = Options(expect=expect, **options)
    markers = load_markers(layout) if layout is not None else None
    cam = load_camera(camera) if camera is not None else None
    ref = read_image(reference) if isinstance(reference, str | Path) else reference
    one = isinstance(photos, str | Path | np.ndarray)
    out = []
    for i, photo in enumerate([photos] if one else list(photos)):
        if isinstance(photo, np.ndarray):
            name = f"photo {i + 1}"
            try:
                out.append(measure_photo(photo, name, opts, markers, cam, ref))
            except VisionError as e:
                out.append(PhotoResult(name, [], [str(e)], None, error=str(e)))
        else:
            out.append(measure_file(photo, opts, markers, cam, ref))
    return out
