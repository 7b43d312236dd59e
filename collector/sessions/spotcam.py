"""The camera of a capture session (``capture --camera``): a photo after standstill, the spot measured
on the sheet through the sheet's markers (``vision.measure``, as ``validate`` and ``spots`` measure a
photo of a layout with markers), in the layout's frame (a sheet's own), with its uncertainty.

Cameras: an OpenCV device (index, URL or ``frames/%04d.png``, as ``validate`` takes them) or ``fake``
(:class:`SheetCamera`): the fake robot's true beam on the printed sheet, seen from a stated pose
(:mod:`collector.hardware.fakeworld`), the sheet's markers and crosses printed, rendered by
``vision.render``. Off the fake backend (a simulator such as franky-sim) the fake camera photographs a
stated true robot's beam at the joint angles the robot reports (:class:`StatedTruth`).
"""

from __future__ import annotations

import sys
import zlib
from dataclasses import dataclass

import numpy as np

from lasercal.collector.errors import SessionError
from lasercal.collector.hardware import fakeworld, truearm
from lasercal.collector.hardware.fakeworld import World, camera_pose, hidden
from lasercal.collector.hardware.truelens import SheetView, SpaceCamera
from lasercal.collector.hardware.truespot import footprint
from lasercal.collector.sessions.exposure import CountedPhotos, FakeExposure
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Layout
from lasercal.solver.kinematics.model import RobotModel
from lasercal.vision.errors import VisionError

PSF_PX = 0.8  # the fake camera's lens blur, px
INK_PX = 0.5  # a spot on printed ink: the bias ink causes, added to its uncertainty (measured: 0.3-0.5 px)
# In a camera session the operator aims beside each cross, on white paper (sheet frame, mm): the camera
# measures where the spot is, and a spot on ink would be biased by the ink that swallows part of it.
BESIDE_MM = (10.0, 10.0)


def sheet_cross(centre: np.ndarray):
    """A cross as ``lasercal sheet`` prints it (vision.sheet: arms from 1.5 to 7 mm off its centre, lines
    0.35 mm, the centre left white), at ``centre`` (the layout's printed x, y, mm)."""
    from lasercal.vision.render import Print, square_corners
    from lasercal.vision.sheet import ARM, LINE

    n = 80  # texels over 14 mm: 0.175 mm each, two per line width
    texel = 2 * ARM[1] / n
    img = np.ones((n, n), np.float32)
    c = (np.arange(n) + 0.5) * texel - ARM[1]
    on_line = np.abs(c) <= LINE / 2
    on_arm = (np.abs(c) >= ARM[0]) & (np.abs(c) <= ARM[1])
    img[np.ix_(on_line, on_arm)] = 0.05
    img[np.ix_(on_arm, on_line)] = 0.05
    return Print(img, square_corners(centre, 2 * ARM[1]))


@dataclass(frozen=True)
class SpotMeasure:
    """A capture's spot as the camera measured it.

    Attributes
    ----------
    xy : (2,) array, the spot in the layout's frame (a sheet's own), mm
    sigma : (2,) array, its 1-sigma uncertainty per axis, mm
    note : str, warnings of the measurement ('' when none)
    """

    xy: np.ndarray
    sigma: np.ndarray
    note: str = ""


@dataclass(frozen=True)
class StatedTruth:
    """A robot off the fake backend as the fake camera sees it: ``truth`` is stated to be the true robot
    (its laser included), at exactly the joint angles ``robot`` reports -- as a simulator's arm is its
    nominal model (franky-sim's is the nominal FR3). No repeatability: the reported pose is the reached one.

    Attributes
    ----------
    truth : RobotModel, the stated true robot, in the frame the sheet's placement is given in
    robot : RobotAdapter, connected while photos are taken
    """

    truth: RobotModel
    robot: object

    def true_q(self) -> np.ndarray:
        """The joint angles the robot reports now, (n,) rad."""
        return self.robot.read().q


class SheetCamera(FakeExposure):
    """Photos of the fake robot's true spot on the printed sheet, from the camera's stated pose, all by the
    world's own code: the beam (:mod:`~collector.hardware.truearm`), where it meets the paper as it truly
    lies (:class:`~collector.hardware.truesheet.PaperSheet`), the lens (:mod:`~collector.hardware.truelens`)
    and the spot (:func:`~collector.hardware.truespot.footprint`); the markers and crosses are printed in
    the layout's coordinates, the paper carries them where they truly are.

    Parameters
    ----------
    robot : FakeRobot or StatedTruth (``true_q()`` and ``truth``)
    markers : vision.plane.MarkerLayout, the layout's markers (sheet frame)
    crosses : (k, 2) array, the layout's points on the sheet, mm
    paper : PaperSheet, where the sheet truly lies in the true robot's frame
    world : World, the effects on
    seed : int, seed of the image noise
    exposure : float or None, a gain on all the light, set through OpenCV's properties
        (:class:`~collector.sessions.exposure.FakeExposure`); None: fixed at 1, as a device that refuses

    Attributes
    ----------
    lens : vision.camera.Camera or None, the correction a measurement applies: the world's calibration
        estimate (``distortion``), None without distortion
    """

    name = "fake"

    def __init__(
        self, robot, markers, crosses, paper, world: World, seed: int = 0, exposure: float | None = None
    ):
        from lasercal.vision.render import aruco_print, reflectance

        self.robot, self.paper, self.world, self.seed, self.exposure = robot, paper, world, seed, exposure
        centre = paper.surface(np.zeros((1, 2)))[0]
        R, t = camera_pose(centre, paper.yaw)
        self.view = SheetView(SpaceCamera(fakeworld.camera_lens(world), R, t), paper)
        self.eye = self.view.camera.eye
        self.lens = world.correction
        prints = tuple(aruco_print(markers.dictionary, i, c) for i, c in markers.corners.items())
        prints += tuple(sheet_cross(p) for p in np.atleast_2d(crosses))
        self.background = reflectance(self.view, prints, PSF_PX)  # the same for every photo: pasted once

    def photo(self) -> np.ndarray:
        """One photo of the sheet with the spot where the true beam meets it, (h, w, 3) BGR uint8."""
        from lasercal.vision.render import Photo, render

        truth, q = self.robot.truth, self.robot.true_q()
        a, d = truearm.beam(truth, q)
        uv, spot, s = self.paper.hit(a, d)
        spots = ()
        seen = not (self.world.has("occlusion") and hidden(truearm.arm_segments(truth, q), self.eye, spot[0]))
        if s[0] > 0 and seen:
            w = self.world
            spots = footprint(
                self.view, self.paper, uv[0], d, w.has("ellipse"), w.has("subsurface"), self.gain
            )
        g = self.gain
        photo = Photo(
            self.view,
            (),
            spots,
            paper=Photo.paper * g,
            psf=PSF_PX,
            gamma=2.2,
            background=self.background,
            camera=self.sensor,
        )
        # the image noise keyed by the pose (itself keyed by the capture): a resumed session repeats itself
        return render(photo, seed=self.seed * 1_000_003 + zlib.crc32(q.tobytes()))

    def close(self) -> None:
        """Nothing to release."""


class PaperTopCamera(CountedPhotos):
    """``validate``'s fake camera over a simulated sheet: a known view straight down at a point of the
    paper as it truly lies (800 mm above it, ``size`` px at ``mm_per_px`` there, no lens distortion), the
    true beam's spot on the paper rendered by the world's own code (:func:`truespot.footprint`, the paper's
    effects on: ``ellipse``, ``subsurface``); ``validate.measure_known_view`` reads the spot's printed
    coordinates back through the same view (it is known: validation measures the model, not the detector).

    Parameters
    ----------
    robot : FakeRobot (``true_beam()``)
    paper : PaperSheet, where the sheet truly lies in the true robot's frame
    centre : (2,) array, the printed point (the layout's x, y, mm) the camera looks at
    world : World, the effects on
    seed : int, seed of the image noise
    size : (w, h) px; mm_per_px : float, at the point
    """

    name = "fake"

    def __init__(self, robot, paper, centre, world: World, seed: int = 0, size=(800, 600), mm_per_px=0.2):
        from lasercal.collector.hardware.truelens import Lens, look_at

        self.robot, self.paper, self.world, self.seed = robot, paper, world, seed
        below = paper.surface(np.asarray(centre, dtype=float)[None])[0]
        R, t = look_at(below + [0.0, 0.0, 800.0], below, up=(np.cos(paper.yaw), np.sin(paper.yaw), 0.0))
        f = 800.0 / mm_per_px
        K = np.array([[f, 0, (size[0] - 1) / 2], [0, f, (size[1] - 1) / 2], [0, 0, 1.0]])
        self.view = SheetView(SpaceCamera(Lens(tuple(size), K), R, t), paper)

    def _render(self, seed: int) -> np.ndarray:
        """A photo of the blank paper with the true beam's spot, (h, w, 3) BGR uint8."""
        from lasercal.vision.render import Photo, render

        a, d = self.robot.true_beam()
        uv, _, s = self.paper.hit(a, d)
        w = self.world
        spots = footprint(self.view, self.paper, uv[0], d, w.has("ellipse"), w.has("subsurface"), self.gain)
        spots = spots if s[0] > 0 else ()
        photo = Photo(self.view, (), spots, paper=Photo.paper * self.gain, camera=self.sensor)
        return render(photo, seed=seed)

    def close(self) -> None:
        """Nothing to release."""


def measure_spot(img: np.ndarray, name: str, markers, lens=None) -> SpotMeasure:
    """The spot of a capture's photo through the sheet's markers (vision), in the layout's frame.

    Raises
    ------
    VisionError
        No spot (hidden by the arm, outside the view, too dim), two candidates, too few markers: one line
        saying why.
    """
    from lasercal.vision.measure import measure_photo

    res = measure_photo(img, name, layout=markers, camera=lens)
    s = res.spots[0]
    if any("outside the area the markers span" in w for w in res.warnings):
        raise VisionError(f"{name}: the spot lies outside the area the markers span (mm extrapolated)")
    sigma = np.array([s.sigma_x_mm, s.sigma_y_mm])
    if s.on_ink:  # ink under the spot swallows part of it: its centre may be off by a few tenths of a pixel
        sigma = np.hypot(sigma, INK_PX * res.plane.mm_per_px)
    return SpotMeasure(np.array([s.x_mm, s.y_mm]), sigma, "; ".join(res.warnings))


def capture_camera(spec: str | None, cfg: dict, robot, layout: Layout, layout_file, world: World):
    """The camera of a capture session and how its photos are measured, or (None, None) without one.

    Parameters
    ----------
    spec : str or None, ``fake``, an OpenCV device index, URL or image sequence; None: no camera
    cfg : dict, the capture settings (``backend``, ``seed``)
    robot : RobotAdapter
    layout : Layout, as loaded (a sheet's points in its own frame)
    layout_file : the layout file, or the session.yaml that copies it: its ``markers`` section
    world : World, the fake world's effects

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
        arm = robot
        if cfg["backend"] != "fake":
            arm = StatedTruth(load_model(cfg["robot"]), robot)
            sys.stderr.write(
                f"--camera fake on --backend {cfg['backend']}: the photos show where the nominal "
                f"{arm.truth.name}'s laser beam (the stated truth, as a simulator's arm is) meets the sheet "
                f"at its placement, at the joint angles the robot reports; world effects: "
                f"{', '.join(world.effects) or 'none'}\n"
            )
        crosses = np.array([p[:2] for p in layout.points.values()])
        paper = world.paper(layout.sheet, layout.plane_z)
        cam = SheetCamera(arm, markers, crosses, paper, world, cfg["seed"])
        return cam, lambda img, name: measure_spot(img, name, markers, cam.lens)
    if spec == "mujoco":  # the MuJoCo world's camera: photos measured as a real camera's are
        from lasercal.collector.hardware.mujoco import mujoco_camera

        return mujoco_camera(robot), lambda img, name: measure_spot(img, name, markers)
    from lasercal.collector.sessions.cameras import OpenCVCamera

    camera = OpenCVCamera(int(spec) if spec.isdigit() else spec)
    return camera, lambda img, name: measure_spot(img, name, markers)
