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
    """

    xy: np.ndarray
    sigma: np.ndarray
    note: str = ""
    eye: np.ndarray | None = None
    in_view: tuple = ()


def measure_spot(img: np.ndarray, name: str, markers, lens=None) -> SpotMeasure:
    """The spot of a capture's photo through the sheet's markers (vision), in the layout's frame.

    Raises
    ------
    VisionError
        No spot (hidden by the arm, outside the view, too dim), two candidates, too few markers: one line
        saying why.
    """
    from lasercal.vision.measure import measure_photo
    from lasercal.vision.plane import camera_eye

    res = measure_photo(img, name, layout=markers, camera=lens)
    s = res.spots[0]
    if any("outside the area the markers span" in w for w in res.warnings):
        raise VisionError(f"{name}: the spot lies outside the area the markers span (mm extrapolated)")
    sigma = np.array([s.sigma_x_mm, s.sigma_y_mm])
    if s.on_ink:  # ink under the spot swallows part of it: its centre may be off by a few tenths of a pixel
        sigma = np.hypot(sigma, INK_PX * res.plane.mm_per_px)
    # a calibration's K; a lens fitted to the markers (rms_px nan) tells no focal length
    cam = res.plane.camera
    calibrated = cam is not None and np.isfinite(getattr(cam, "rms_px", np.nan))
    eye = camera_eye(res.plane.H, (img.shape[1], img.shape[0]), cam.K if calibrated else None)
    found = tuple(int(i) for i in res.plane.fiducials.marker_ids)
    return SpotMeasure(np.array([s.x_mm, s.y_mm]), sigma, "; ".join(res.warnings), eye, found)


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
        return cam, lambda img, name: measure_spot(img, name, markers, cam.lens)
    if spec == "mujoco":  # the MuJoCo world's camera: photos measured as a real camera's are
        return mujoco_camera(robot), lambda img, name: measure_spot(img, name, markers)
    from lasercal.collector.hardware.cameras import OpenCVCamera

    camera = OpenCVCamera(int(spec) if spec.isdigit() else spec)
    return camera, lambda img, name: measure_spot(img, name, markers)
