"""The simulated worlds' cameras: what a camera on the fake bench photographs, rendered by ``vision.render``.

* :class:`SheetCamera`: a capture session's camera (``capture --camera fake``): the fake robot's true beam on
  the printed sheet, seen from a stated pose through the world's lens (:mod:`.truelens`), the sheet's markers
  and crosses printed; off the fake backend (a simulator such as franky-sim) it photographs a stated true
  robot's beam at the joint angles the robot reports (:class:`StatedTruth`);
* :class:`PaperTopCamera`: a validation's camera looking down at a point of the world's true paper;
* :class:`FakeCamera`: a validation's camera on a base-frame layout: the spot on a blank sheet.

Each has OpenCV's exposure properties (:class:`FakeExposure`), so the exposure control a session runs on a
real camera runs on it unchanged.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import cv2
import numpy as np

from lasercal.collector.hardware.cameras import AUTO_OFF
from lasercal.collector.worlds import fakeworld, truearm
from lasercal.collector.worlds.fakeworld import World, camera_pose, hidden
from lasercal.collector.worlds.truelens import SheetView, SpaceCamera
from lasercal.collector.worlds.truespot import footprint
from lasercal.solver.kinematics.model import RobotModel
from lasercal.vision.render import LaserSpot, Photo, View, look_down, render

PSF_PX = 0.8  # the fake camera's lens blur, px
FAKE_VIEW_PX = (800, 600)
FAKE_MM_PER_PX = 0.2
PAPER = Photo.paper  # the blank sheet's brightness at exposure 1, of full scale


class FakeExposure:
    """OpenCV's exposure properties on a fake camera: ``exposure`` multiplies all the light it renders
    (None: a camera whose exposure cannot be set, as the fake cameras were before: nothing changes).

    A camera whose exposure is modelled renders through a sensor that clips as a phone's does
    (:class:`vision.render.PhoneCamera`: Bayer mosaic, blooming, colour matrix, JPEG; its auto exposure off,
    the exposure being the tool's): the fake cameras' own rendering clips a spot into a symmetric plateau,
    which costs its centre nothing, and would not show what clipping costs.
    """

    exposure: float | None = None

    @property
    def exposure_control(self) -> bool:
        return self.exposure is not None

    @property
    def gain(self) -> float:
        return 1.0 if self.exposure is None else float(self.exposure)

    @property
    def sensor(self):
        """The phone-like sensor photos are rendered through, or None (the fake camera's own)."""
        from lasercal.vision.render import PhoneCamera

        return None if self.exposure is None else PhoneCamera(ae_target=None, ae_stops=0.0)

    def get(self, prop) -> float:
        if prop == cv2.CAP_PROP_AUTO_EXPOSURE:
            return AUTO_OFF[0] if self.exposure is not None else 0.0
        if prop == cv2.CAP_PROP_EXPOSURE:
            return self.gain
        return 0.0

    def set(self, prop, value) -> bool:
        if self.exposure is None or prop not in (cv2.CAP_PROP_AUTO_EXPOSURE, cv2.CAP_PROP_EXPOSURE):
            return False
        if prop == cv2.CAP_PROP_EXPOSURE:
            self.exposure = float(value)
        return True


class CountedPhotos(FakeExposure):
    """A validation's fake camera: the photos' noise is keyed by their count, a live frame (the view's) has
    noise of its own, so a view leaves the validation's photos as they would be without it. A subclass
    renders one picture with ``_render(seed)`` and sets ``seed``."""

    seed: int = 0
    _count = _frames = 0  # photos and frames taken (set on the instance by the first of each)

    def photo(self) -> np.ndarray:
        """One photo, (h, w, 3) BGR uint8."""
        self._count += 1
        return self._render(self.seed + self._count)

    def frame(self) -> np.ndarray:
        """A live frame for the view: rendered as a photo is, with noise of its own."""
        self._frames += 1
        return self._render(self.seed - self._frames)

    def _render(self, seed: int) -> np.ndarray:
        raise NotImplementedError


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
    world's own code: the beam (:mod:`~collector.worlds.truearm`), where it meets the paper as it truly
    lies (:class:`~collector.worlds.truesheet.PaperSheet`), the lens (:mod:`~collector.worlds.truelens`)
    and the spot (:func:`~collector.worlds.truespot.footprint`); the markers and crosses are printed in
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
        (:class:`FakeExposure`); None: fixed at 1, as a device that refuses

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
        from lasercal.collector.worlds.truelens import Lens, look_at

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


def fake_view(centre_xy, plane_z: float, size=(1600, 1200), mm_per_px: float = 0.1) -> View:
    """A camera 800 mm above the table looking straight down at ``centre_xy`` (mm)."""
    return look_down(size=size, mm_per_px=mm_per_px, centre=tuple(centre_xy), height=800.0, z=plane_z)


# The fake camera of `validate`: 160 x 120 mm around the point (a nominal model's spots land up to ~30 mm
# off) at 0.2 mm/px, where the spot (sigma 2.5 px, 0.5 mm) is measured to ~0.01 mm; a quarter of the pixels
# of 0.1 mm/px, which made rendering, measuring and storing the photos 80 % of a run's time.


@dataclass(frozen=True)
class SpotLook:
    """How the fake laser spot looks: Gaussian sigma (px), peak (full scale), speckle contrast."""

    sigma: float = 2.5
    peak: float = 0.8
    speckle: float = 0.2


class FakeCamera(CountedPhotos):
    """Photos of the spot the fake robot's true beam makes on a blank sheet.

    No reference marks are printed: ink under the spot would bias its centroid, and the
    validation measures the model, not the spot detector.

    Parameters
    ----------
    robot : FakeRobot (anything with ``true_spot(z) -> (spot, length)``)
    view : vision.render.View
    plane_z : float, mm
    seed : int, seed of the image noise
    look : SpotLook
    exposure : float or None, a gain on all the light, set through OpenCV's properties
        (:class:`FakeExposure`); None: fixed at 1, as a device that refuses
    """

    name = "fake"

    def __init__(
        self,
        robot,
        view: View,
        plane_z: float,
        seed: int = 0,
        look: SpotLook = SpotLook(),
        exposure: float | None = None,
    ):
        self.robot, self.view, self.plane_z, self.seed, self.look = robot, view, plane_z, seed, look
        self.exposure = exposure

    def _render(self, seed: int) -> np.ndarray:
        spot, _ = self.robot.true_spot(self.plane_z)
        u, v = self.view.project(spot[:2])[0]
        lk, g = self.look, self.gain
        spot = LaserSpot(u, v, lk.sigma, lk.peak * g, lk.speckle)
        photo = Photo(self.view, (), (spot,), paper=PAPER * g, camera=self.sensor)
        return render(photo, seed=seed)

    def close(self) -> None:
        """Nothing to release."""
