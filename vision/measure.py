"""One photo in, spots in pixels and millimetres out: the pipeline behind the CLI.

Pixels in OpenCV's convention (ImageJ's is +0.5 px, applied only on output), mm
in the robot base frame on the layout's plane.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import cv2
import numpy as np

from lasercal.vision.camera import Camera
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import MeasureFault, VisionError
from lasercal.vision.exposure import Exposure, exposure_advice
from lasercal.vision.images import chroma_subsampled, full_scale, read_image, to_gray
from lasercal.vision.plane import MarkerLayout, PlaneMap, find_fiducials, fit_lens, fit_plane
from lasercal.vision.spot import Spot, with_plane


@dataclass(frozen=True)
class Options:
    """How to measure (see ``lasercal spots --help``)."""

    method: str = "precise"  # precise | imagej
    imagej_mode: str = "centroid"  # centroid | com
    imagej_threshold: str = "default"  # default | otsu
    imagej_box: int = 64  # side of the box drawn around a spot, px; 0: the whole photo
    colour: str = "auto"  # red | green | auto (decided per photo from the photo)
    expect: int | None = 1  # None: any number of spots
    gamma: float = 2.2  # the photos' encoding gamma, for marker corners and spots on ink
    channel: str = "auto"  # precise centroid on: laser | luma | auto (luma for chroma-subsampled JPEGs)


@dataclass(frozen=True)
class PhotoResult:
    """Spots of one photo, with the warnings and the plane map (None without markers).

    Attributes
    ----------
    name : str
    spots : list of Spot; each spot's ``evidence`` says why it was taken for laser light
    warnings : list of str (the exposure advice among them)
    plane : PlaneMap or None
    colour : str or None, the laser colour measured ("red" or "green"; with ``--color auto``
        decided from the photo), None when the photo was lost
    exposure : Exposure or None, clipping, contrast and one line of advice for the operator
    error : str or None, one line saying why the photo was lost (then there are no spots)
    """

    name: str
    spots: list
    warnings: list
    plane: PlaneMap | None
    colour: str | None = None
    exposure: Exposure | None = None
    error: str | None = None

    def to_dict(self, method: str, convention: str = "opencv", plane_z: float | None = None) -> dict:
        """The photo's JSON entry (``lasercal spots --json``): spots in ``convention``, the plane fit."""
        pm = self.plane
        plane = None
        if pm is not None:
            plane = {
                "markers": list(pm.fiducials.marker_ids),
                "charuco_corners": pm.fiducials.charuco,
                "rms_mm": round(pm.rms_mm, 4),
                "max_mm": round(pm.max_mm, 4),
                "outliers": int((~pm.inliers).sum()),
                "mm_per_px": round(pm.mm_per_px, 5),
                "z_mm": plane_z,
            }
        entry = {
            "image": self.name,
            "spots": spot_dicts(self.spots, convention),
            "warnings": list(self.warnings),
            "error": self.error,
            "plane": plane,
            "method": method,
            "convention": convention,
        }
        if self.error is None:
            entry["colour"] = self.colour
            entry["exposure"] = self.exposure.to_dict() if self.exposure else None
        return entry


def measure_photo(
    img: np.ndarray,
    name: str,
    opts: Options = Options(),
    layout: MarkerLayout | None = None,
    camera: Camera | None = None,
    reference: np.ndarray | None = None,
    subsampled: bool = False,
    predicted: tuple[float, float, float] | None = None,
) -> PhotoResult:
    """Detect and measure the spots of one photo, on the plane when the layout has markers.

    With a layout the markers are found first, and the spot is sought on the sheet only (the
    markers' hull grown 2x about its centre): red and bright things around it are no candidates.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16
    name : str, for messages
    opts : Options
    layout : MarkerLayout or None
    camera : Camera or None, lens distortion to undo before the homography
    reference : laser-off photo like ``img`` or None
    subsampled : bool, the photo is a JPEG with chroma subsampling (see ``images.chroma_subsampled``)
    predicted : (u, v, sigma) px or None, where the spot is expected (see ``detect_spots``)

    Raises
    ------
    VisionError
        No spot, too many spots, too few markers, wrong image size, a blank or tiny photo:
        the photo is lost.
    """
    check_photo(img, name)
    size = (img.shape[1], img.shape[0])
    if camera is not None:
        camera.check_size(size, name)
    luma = opts.channel == "luma" or (opts.channel == "auto" and subsampled)
    plane, fid, lost, lens_note, lens = None, None, None, None, None
    if layout is not None:
        try:  # the markers first: they bound the search; a photo without them is lost all the same
            with stage(name, "finding the markers"):
                fid = find_fiducials(to_gray(img), layout, opts.gamma, camera)
            with stage(name, "fitting the plane"):
                plane = fit_plane(fid, layout, camera, size, name)
            if camera is None:
                plane, fid, lens, lens_note = _lens_from_markers(img, name, layout, opts.gamma, plane, fid)
        except VisionError as exc:
            lost = exc
    with stage(name, "finding the laser spot"):
        spots, warnings = detect_spots(
            img,
            name,
            opts.colour,
            reference,
            opts.expect,
            opts.method,
            opts.imagej_mode,
            opts.imagej_threshold,
            opts.imagej_box,
            opts.gamma,
            luma,
            search=None if plane is None else sheet_region(plane, layout),
            predicted=predicted,
        )
    if lost is not None:
        raise lost
    exposure = exposure_advice(spots, reference is not None) if opts.method == "precise" else None
    if exposure is not None and exposure.advice:
        warnings.append(exposure.advice)
    colour = next(
        (s.evidence.colour for s in spots if s.evidence is not None and s.evidence.colour), opts.colour
    )
    if lens_note:
        warnings.append(lens_note)
    if plane is not None:
        if fid.unknown_ids:
            warnings.append(f"markers not in the layout ignored: ids {', '.join(map(str, fid.unknown_ids))}")
        if (~plane.inliers).any():
            warnings.append(left_out_note(fid, plane.inliers))
        uv = np.array([[s.u, s.v] for s in spots])
        xy = plane.to_plane(uv)
        sig_uv = np.array([[s.sigma_u or 0.0, s.sigma_v or 0.0] for s in spots])
        sig_xy = plane.sigma_mm(uv, sig_uv)
        if lens is not None:  # the lens fitted to the markers is known only as well as they tell it
            sig_xy = np.hypot(sig_xy, lens.sigma_mm(fid, plane.inliers, uv))
        has_sigma = [s.sigma_u is not None for s in spots]
        spots = [
            with_plane(s, float(p[0]), float(p[1]), float(e[0]) if ok else None, float(e[1]) if ok else None)
            for s, p, e, ok in zip(spots, xy, sig_xy, has_sigma)
        ]
        outside = ~plane.inside(uv)
        if outside.any():
            warnings.append(
                f"{int(outside.sum())} spot(s) outside the area the markers span: mm extrapolated"
            )
    return PhotoResult(name, spots, warnings, plane, colour, exposure)


def left_out_note(fid, inliers: np.ndarray) -> str:
    """What the fiducial corners the plane left out (more than 2 mm off the layout) say, marker by marker: a
    marker with only some corners off was partly hidden or shadowed (an edge found where the shadow's is);
    one with every corner off lies elsewhere than the layout says (a wrong id or corner order, or a marker
    moved); ChArUco corners are counted apart."""
    k = len(fid.marker_ids)
    off = ~np.asarray(inliers, bool)
    per_marker = off[: 4 * k].reshape(k, 4)
    part = [str(i) for i, row in zip(fid.marker_ids, per_marker) if row.any() and not row.all()]
    whole = [str(i) for i, row in zip(fid.marker_ids, per_marker) if row.all()]
    said = []
    if part:
        said.append(f"marker{'s' if len(part) > 1 else ''} {', '.join(part)} partly hidden or shadowed")
    if whole:
        said.append(
            f"marker{'s' if len(whole) > 1 else ''} {', '.join(whole)} not where the layout says "
            "(a wrong id or corner order, or moved)"
        )
    if off[4 * k :].any():
        said.append(f"{int(off[4 * k :].sum())} ChArUco corners off")
    return (
        f"{int(off.sum())} fiducial corners disagree with the layout by more than 2 mm and were left out: "
        + "; ".join(said)
    )


def _lens_from_markers(img, name, layout, gamma, plane, fid):
    """The plane (and fiducials) through a lens fitted to the markers when they show one
    (:func:`~vision.plane.fit_lens`: a capture that knows its camera's calibration measures the same
    photo through it), the lens and a warning saying so; else the plane as it was, None and None."""
    size = (img.shape[1], img.shape[0])
    with stage(name, "fitting a lens to the markers"):
        lens = fit_lens(plane, size)
        if lens is None:
            return plane, fid, None, None
        fid_l = find_fiducials(to_gray(img), layout, gamma, lens.camera)
        plane_l = fit_plane(fid_l, layout, lens.camera, size, name)
    if plane_l.rms_mm >= plane.rms_mm:  # the corners found through the lens must agree better still
        return plane, fid, None, None
    k1, k2, f = lens.camera.dist[0], lens.camera.dist[1], lens.camera.K[0, 0]
    note = (
        f"the markers bend off a plane by {plane.rms_mm:.3f} mm RMS: a lens distortion fitted to them "
        f"(k1 {k1:+.4f}, k2 {k2:+.4f} at f = {f:.0f} px) brings that to {plane_l.rms_mm:.3f} mm and is "
        "undone before the mm (a camera YAML from camera-calibrate, --camera, is better)"
    )
    return plane_l, fid_l, lens, note


def sheet_region(plane: PlaneMap, layout: MarkerLayout, grow: float = 2.0) -> np.ndarray:
    """The part of the photo a spot is sought in when the markers are found: the hull of all the
    layout's fiducials on the plane (found in this photo or not), grown by ``grow`` about its centre
    (markers sit inside the sheet, and spots are measured around them), mapped into the photo, px.

    Returns
    -------
    (n, 2) float32 array, a polygon in the stored pixel grid
    """
    pts = [plane.fiducials.plane.reshape(-1, 2)]
    pts += [np.asarray(c, float).reshape(-1, 2) for c in layout.corners.values()]
    if layout.charuco is not None:  # the board's outer corners, not only the inner ones found
        ch = layout.charuco
        w, h = ch.squares[0] * ch.square, ch.squares[1] * ch.square
        pts.append(ch.origin + np.array([[0, 0], [w, 0], [w, h], [0, h]]) @ np.array([ch.x_axis, ch.y_axis]))
    xy = np.concatenate(pts).astype(np.float32)
    hull = cv2.convexHull(xy).reshape(-1, 2).astype(float)
    centre = hull.mean(axis=0)
    uv = plane.to_image(centre + grow * (hull - centre))
    return np.clip(uv, -1e6, 1e6).astype(np.float32)


@contextmanager
def stage(name: str, what: str):
    """Turn a fault inside one stage of the measurement into a one-line :class:`MeasureFault`.

    A photo that OpenCV decodes must never end in a traceback: whatever a library raises on it
    (an assertion on an odd size, a numerical failure) becomes one line naming the photo and the
    stage, and the batch goes on.
    """
    try:
        yield
    except VisionError:
        raise
    except Exception as exc:  # any fault of ours: reported in one line, not raised raw
        last = (str(exc).strip().splitlines() or [""])[-1][:200]
        raise MeasureFault(
            f"{name}: could not be measured: internal error while {what} ({type(exc).__name__}: {last})"
        ) from exc


MIN_SIDE = 16  # px: a smaller photo cannot hold a spot and the paper around it


def check_photo(img: np.ndarray, name: str) -> None:
    """Refuse photos that cannot hold a measurable spot, with a one-line reason.

    Raises
    ------
    VisionError
        Smaller than 16 px on a side, or blank: all black or all white (clipped).
    """
    h, w = img.shape[:2]
    if min(h, w) < MIN_SIDE:
        raise VisionError(
            f"{name}: image is {w}x{h} px, too small to hold a laser spot and the paper around it"
        )
    lo, hi = cv2.minMaxLoc(img.reshape(h, -1))[:2]
    full = full_scale(img)
    if hi <= 0.02 * full:
        raise VisionError(f"{name}: the photo is black (lens covered, or far too dark: raise the exposure)")
    if lo >= 0.98 * full:
        raise VisionError(f"{name}: the photo is white, clipped everywhere (lower the exposure)")


def measure_file(
    path,
    opts: Options = Options(),
    layout: MarkerLayout | None = None,
    camera: Camera | None = None,
    reference: np.ndarray | None = None,
) -> PhotoResult:
    """Read and measure one photo; never raises on a bad photo.

    Parameters
    ----------
    path : str or Path
    opts, layout, camera, reference : as for :func:`measure_photo`

    Returns
    -------
    PhotoResult; when the photo is lost, ``error`` says why in one line (also the only warning)
    and ``spots`` is empty
    """
    name = str(path)
    try:
        with stage(name, "reading the photo"):
            img = read_image(path)
        return measure_photo(img, name, opts, layout, camera, reference, chroma_subsampled(path))
    except VisionError as exc:
        why = str(exc)
    return PhotoResult(name, [], [why], None, error=why)


def measure_batch(
    paths,
    opts: Options = Options(),
    layout: MarkerLayout | None = None,
    camera: Camera | None = None,
    reference: np.ndarray | None = None,
) -> list[PhotoResult]:
    """:func:`measure_file` for each photo, in order; a lost photo does not stop the batch."""
    return [measure_file(p, opts, layout, camera, reference) for p in paths]


def median_reference(paths: list[str]) -> np.ndarray:
    """Per-pixel median of a photo series: the laser-free background when the spot moves.

    Raises
    ------
    VisionError
        Fewer than 3 photos, or photos of different sizes.
    """
    if len(paths) < 3:
        raise VisionError(f"--reference median needs at least 3 photos of one view, got {len(paths)}")
    imgs = [read_image(p) for p in paths]
    if len({i.shape for i in imgs}) != 1:
        raise VisionError("--reference median: the photos differ in size")
    return np.median(np.stack(imgs), axis=0).astype(imgs[0].dtype)


def spot_dicts(spots: list[Spot], convention: str) -> list[dict]:
    """JSON-ready spots."""
    return [s.to_dict(convention) for s in spots]
