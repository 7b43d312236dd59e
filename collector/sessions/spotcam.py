"""The camera of a capture session (``capture --camera``): a photo after standstill, the spot measured
on the sheet through the sheet's markers (``vision.measure``, as ``validate`` and ``spots`` measure a
photo of a layout with markers), in the layout's frame (a sheet's own), with its uncertainty.

Cameras: an OpenCV device (index, URL or ``frames/%04d.png``, as ``validate`` takes them) or ``fake``
(:class:`SheetCamera`): the fake robot's true beam on the printed sheet, seen from a stated pose
(:mod:`collector.worlds.fakeworld`), the sheet's markers and crosses printed, rendered by
``vision.render``. Off the fake backend (a simulator such as franky-sim) the fake camera photographs a
stated true robot's beam at the joint angles the robot reports (:class:`StatedTruth`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.collector.errors import SessionError
from lasercal.collector.hardware import mujoco_camera, sheet_camera
from lasercal.solver.formats.session import Layout
from lasercal.vision.errors import VisionError

PSF_PX = 0.8  # the fake camera's lens blur, px
INK_PX = 0.5  # a spot on printed ink: the bias ink causes, added to its uncertainty (measured: 0.3-0.5 px)
# In a camera session the operator aims beside each cross, on white paper (sheet frame, mm): the camera
# measures where the spot is, and a spot on ink would be biased by the ink that swallows part of it.
BESIDE_MM = (10.0, 10.0)
# px: the most the median marker corner may move between two photos of a camera that has not moved. The
# fake camera's corners repeat to a median of 0.009-0.014 px over 19 photos (the arm's shadow moves a few
# by up to 0.37 px), MuJoCo's exactly; a camera bumped by this much moves a spot ~0.06 mm on an A4 sheet.
UNMOVED_PX = 0.25


@dataclass(frozen=True)
class SpotMeasure:
    """A capture's spot as the camera measured it.

    Attributes
    ----------
    xy : (2,) array, the spot in the layout's frame (a sheet's own), mm
    sigma : (2,) array, its 1-sigma uncertainty per axis, mm
    note : str, warnings of the measurement ('' when none)
    eye : (3,) array or None, where the camera stands in the layout's frame, mm, from the photo's markers
        (:func:`vision.plane.camera_eye`, eq. V2; None when they cannot tell)
    in_view : tuple of int, the ids of the markers the photo found (the others hidden or out of its frame)
    plane : vision.plane.PlaneMap or None, the photo's own map to the sheet
    """

    xy: np.ndarray
    sigma: np.ndarray
    note: str = ""
    eye: np.ndarray | None = None
    in_view: tuple = ()
    plane: object = None


def measure_spot(img: np.ndarray, name: str, markers, lens=None, view=None) -> SpotMeasure:
    """The spot of a capture's photo through the sheet's markers (vision), in the layout's frame.

    Parameters
    ----------
    img : (h, w, 3) uint8 array, the photo
    name : str, what messages call it
    markers : vision.plane.MarkerLayout, the sheet's markers
    lens : vision.plane.Camera or None, the camera's lens (None: fitted to the markers)
    view : vision.plane.PlaneMap or None, the session's widest view of the markers from the same fixed
        camera (:class:`SpotMeter`): a spot outside the markers this photo shows (the arm hides one) is
        mapped through it when this photo's markers say the camera has not moved (:func:`unmoved`)

    Raises
    ------
    VisionError
        No spot (hidden by the arm, outside the view, too dim), two candidates, too few markers, a spot
        outside the markers' area that no view of an unmoved camera spans: one line saying why.
    """
    from lasercal.vision.measure import measure_photo
    from lasercal.vision.plane import camera_eye

    res = measure_photo(img, name, layout=markers, camera=lens)
    s, plane, notes = res.spots[0], res.plane, list(res.warnings)
    xy, sigma = np.array([s.x_mm, s.y_mm]), np.array([s.sigma_x_mm, s.sigma_y_mm])
    outside = [w for w in notes if "outside the area the markers span" in w]
    if outside:
        uv, sig_uv = np.array([[s.u, s.v]]), np.array([[s.sigma_u or 0.0, s.sigma_v or 0.0]])
        if view is None or not view.inside(uv)[0] or not unmoved(view, plane):
            raise VisionError(f"{name}: the spot lies outside the area the markers span (mm extrapolated)")
        # the photo's own terms beyond its map's (a lens fitted to the markers) carry over to the view's
        own = np.sqrt(np.maximum(sigma**2 - plane.sigma_mm(uv, sig_uv)[0] ** 2, 0.0))
        xy, sigma = view.to_plane(uv)[0], np.hypot(view.sigma_mm(uv, sig_uv)[0], own)
        hidden = sorted(set(view.fiducials.marker_ids) - set(plane.fiducials.marker_ids))
        notes = [w for w in notes if w not in outside] + [
            f"markers {', '.join(map(str, hidden))} hidden: mapped through the session's view of "
            f"{len(view.fiducials.marker_ids)} markers (the camera unmoved)"
        ]
    if s.on_ink:  # ink under the spot swallows part of it: its centre may be off by a few tenths of a pixel
        sigma = np.hypot(sigma, INK_PX * plane.mm_per_px)
    # a calibration's K; a lens fitted to the markers (rms_px nan) tells no focal length
    cam = plane.camera
    calibrated = cam is not None and np.isfinite(getattr(cam, "rms_px", np.nan))
    eye = camera_eye(plane.H, (img.shape[1], img.shape[0]), cam.K if calibrated else None)
    found = tuple(int(i) for i in plane.fiducials.marker_ids)
    return SpotMeasure(xy, sigma, "; ".join(notes), eye, found, plane)


def unmoved(view, plane, limit_px: float = UNMOVED_PX) -> bool:
    """Whether a photo's map ``plane`` and an earlier ``view`` (vision.plane.PlaneMap) come from a camera
    that has not moved: the corners of the markers both found lie where they were, the median of their
    displacements within ``limit_px`` (a median, so that the corners the arm's shadow moves do not count)."""
    was = dict(zip(view.fiducials.marker_ids, view.fiducials.marker_corners))
    now = dict(zip(plane.fiducials.marker_ids, plane.fiducials.marker_corners))
    both = [i for i in now if i in was]
    if not both:
        return False
    moved = np.linalg.norm(np.concatenate([now[i] - was[i] for i in both]), axis=1)
    return bool(np.median(moved) <= limit_px)


class SpotMeter:
    """How a session's photos are measured (:func:`measure_spot`), remembering the widest view of the
    markers its fixed camera has given (the map fitted to the most fiducials; replaced only by one of an
    unmoved camera): a photo in which the arm hides a marker is measured through it.

    Called as ``meter(img, name) -> SpotMeasure``.
    """

    def __init__(self, markers, lens=None):
        self.markers, self.lens, self.view = markers, lens, None

    def __call__(self, img: np.ndarray, name: str) -> SpotMeasure:
        got = measure_spot(img, name, self.markers, self.lens, self.view)
        wider = self.view is None or got.plane.inliers.sum() > self.view.inliers.sum()
        if wider and (self.view is None or unmoved(self.view, got.plane)):
            self.view = got.plane
        return got


def capture_camera(spec: str | None, cfg: dict, robot, layout: Layout, layout_file, world):
    """The camera of a capture session and how its photos are measured, or (None, None) without one.

    Parameters
    ----------
    spec : str or None, ``fake``, an OpenCV device index, URL or image sequence; None: no camera
    cfg : dict, the capture settings (``backend``, ``seed``)
    robot : RobotAdapter
    layout : Layout, as loaded (a sheet's points in its own frame)
    layout_file : the layout file, or the session.yaml that copies it: its ``markers`` section
    world : collector.worlds.fakeworld.World, the fake world's effects

    A fake camera off the fake backend (a simulator) photographs where the nominal model ``cfg["robot"]``
    names, laser included, puts the beam at the joint angles the robot reports (:class:`StatedTruth`);
    one line on stderr says so.

    Returns
    -------
    (camera, measure): ``measure(img, name) -> SpotMeasure``

    Raises
    ------
    SessionError
        A fake camera on a layout without a placement; a layout without markers.
    """
    if spec is None:
        return None, None
    from lasercal.vision.plane import load_markers

    markers = load_markers(layout_file)
    if markers is None:
        raise SessionError(
            f"--camera: the layout {layout_file} has no markers section: the camera finds the spot on the "
            "sheet through its markers (print a sheet with lasercal sheet)"
        )
    if spec == "fake":
        if layout.frame != "sheet" or layout.sheet is None:
            raise SessionError("--camera fake needs a sheet layout with a placement (lasercal sheet --place)")
        cam = sheet_camera(cfg, robot, layout, markers, world)
        return cam, SpotMeter(markers, cam.lens)
    if spec == "mujoco":  # the MuJoCo world's camera: photos measured as a real camera's are
        return mujoco_camera(robot), SpotMeter(markers)
    from lasercal.collector.hardware.cameras import OpenCVCamera

    camera = OpenCVCamera(int(spec) if spec.isdigit() else spec)
    return camera, SpotMeter(markers)
