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
from lasercal.collector.hardware import fakeworld
from lasercal.collector.hardware.fakeworld import World, arm_capsules, camera_pose, hidden
from lasercal.collector.sessions.exposure import FakeExposure
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Layout
from lasercal.solver.kinematics.laser import LaserParams
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.sheet import SheetPose
from lasercal.vision.errors import VisionError

PSF_PX = 0.8  # the fake camera's lens blur, px
SPOT_PEAK = 0.3  # the spot's peak at normal incidence, of full scale: exposed not to clip on the paper
INK_PX = 0.5  # a spot on printed ink: the bias ink causes, added to its uncertainty (measured: 0.3-0.5 px)
# In a camera session the operator aims beside each cross, on white paper (sheet frame, mm): the camera
# measures where the spot is, and a spot on ink would be biased by the ink that swallows part of it.
BESIDE_MM = (10.0, 10.0)


def sheet_cross(centre: np.ndarray, scale: np.ndarray):
    """A cross as ``lasercal sheet`` prints it (vision.sheet: arms from 1.5 to 7 mm off its centre, lines
    0.35 mm, the centre left white), at ``centre`` (base x, y, mm; the sheet's axes along the base's up to
    its yaw, which the texture ignores: crosses are symmetric), scaled by the printer."""
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
    return Print(img, square_corners(centre, 2 * ARM[1] * float(np.mean(scale))))


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
    """Photos of the fake robot's true spot on the printed sheet, from the camera's stated pose.

    Parameters
    ----------
    robot : FakeRobot or StatedTruth (``true_q()`` and ``truth``)
    markers : vision.plane.MarkerLayout, the layout's markers (sheet frame)
    crosses : (k, 2) array, the layout's points on the sheet, mm
    pose : SheetPose, where the sheet truly lies in the true robot's frame
    plane_z : float, the sheet's stated height, mm
    world : World, the effects on
    seed : int, seed of the image noise
    exposure : float or None, a gain on all the light, set through OpenCV's properties
        (:class:`~collector.sessions.exposure.FakeExposure`); None: fixed at 1, as a device that refuses
    """

    name = "fake"

    def __init__(
        self,
        robot,
        markers,
        crosses,
        pose: SheetPose,
        plane_z: float,
        world: World,
        seed: int = 0,
        exposure: float | None = None,
    ):
        from lasercal.vision.camera import Camera
        from lasercal.vision.render import aruco_print, pose_view, reflectance

        self.robot, self.pose, self.world, self.seed, self.exposure = robot, pose, world, seed, exposure
        self.z = plane_z + world.sheet_dz  # the sheet's true surface
        centre = pose.to_base(np.zeros((1, 2)), self.z)[0]
        R, t = camera_pose(centre, np.radians(pose.yaw_deg))
        self.eye = -R.T @ t
        w, h = fakeworld.CAMERA_PX
        f = np.linalg.norm(self.eye - centre) / fakeworld.CAMERA_MM_PER_PX
        K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
        dist = np.array(fakeworld.DISTORTION if world.has("distortion") else np.zeros(5), dtype=float)
        self.view = pose_view((w, h), K, dist, R, t, self.z)
        self.lens = Camera((w, h), K, dist) if world.has("distortion") else None
        S = world.print_scale

        def printed(xy):  # sheet mm as printed (scaled) to base-frame x, y
            return pose.to_base(np.asarray(xy, dtype=float) * S, self.z)[:, :2]

        prints = tuple(aruco_print(markers.dictionary, i, printed(c)) for i, c in markers.corners.items())
        prints += tuple(sheet_cross(printed(p[None])[0], S) for p in np.atleast_2d(crosses))
        self.background = reflectance(self.view, prints, PSF_PX)  # the same for every photo: pasted once

    def photo(self) -> np.ndarray:
        """One photo of the sheet with the spot where the true beam meets it, (h, w, 3) BGR uint8."""
        from lasercal.vision.render import Photo, render

        truth, q = self.robot.truth, self.robot.true_q()
        P = LaserParams(truth)
        b = P.beam(P.x0(), q[None])
        a, d = b.aperture[0], b.direction[0]
        spot = a + (self.z - a[2]) / d[2] * d
        spots = ()
        if d[2] < 0 and not (self.world.has("occlusion") and hidden(arm_capsules(truth, q), self.eye, spot)):
            spots = (self._spot(spot[:2], d),)
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

    def _spot(self, xy: np.ndarray, d: np.ndarray):
        """The footprint of a beam of direction d at xy (mm) as a LaserSpot in pixels: round on the sheet
        (sigma BEAM_SIGMA_MM), stretched by 1/cos(tilt) along its azimuth with ``ellipse``, through the
        view's local Jacobian."""
        from lasercal.vision.render import LaserSpot

        cov = np.eye(2) * fakeworld.BEAM_SIGMA_MM**2
        horiz = np.hypot(d[0], d[1])
        if self.world.has("ellipse") and horiz > 1e-9:
            az = d[:2] / horiz
            cos_t = -d[2]
            cov += (1 / cos_t**2 - 1) * fakeworld.BEAM_SIGMA_MM**2 * np.outer(az, az)
        h = 0.01
        uv = self.view.project(xy[None])[0]
        project = self.view.project
        J = np.column_stack([(project(xy + e) - project(xy - e))[0] / (2 * h) for e in np.eye(2) * h])
        C = J @ cov @ J.T
        val, vec = np.linalg.eigh(C)
        major = np.sqrt(val[1])
        angle = np.degrees(np.arctan2(vec[1, 1], vec[0, 1]))
        irradiance = self.gain * SPOT_PEAK * fakeworld.BEAM_SIGMA_MM**2 / np.sqrt(np.linalg.det(cov))
        aspect = np.sqrt(val[0]) / major
        return LaserSpot(uv[0], uv[1], major, irradiance, 0.2, aspect=aspect, angle_deg=angle)

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
        cam = SheetCamera(arm, markers, crosses, layout.sheet, layout.plane_z, world, cfg["seed"])
        return cam, lambda img, name: measure_spot(img, name, markers, cam.lens)
    if spec == "mujoco":  # the MuJoCo world's camera: photos measured as a real camera's are
        from lasercal.collector.hardware.mujoco import mujoco_camera

        return mujoco_camera(robot), lambda img, name: measure_spot(img, name, markers)
    from lasercal.collector.sessions.cameras import OpenCVCamera

    camera = OpenCVCamera(int(spec) if spec.isdigit() else spec)
    return camera, lambda img, name: measure_spot(img, name, markers)
