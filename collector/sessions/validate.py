"""The validation session (``lasercal validate``): the thesis's Section 4.3 check, automated.

A model computes N diverse configurations that it says put the spot on the validation
point; the arm goes to each (moved by backends that can move, otherwise guided by the
operator), a camera photographs the spot, and validation.csv records the measured
configuration and the photo. Where the photo can be mapped to the plane -- the fake
camera's known view, or a layout with fiducial markers -- the spot is measured at once
(``x_mm, y_mm``); otherwise the photos are kept unmeasured (``lasercal spots`` shows them; the report needs
measured spots: validate through a layout with markers).

Cameras: an OpenCV capture device (index, URL, or an image sequence such as
``frames/%04d.png``), or ``fake``, which renders the spot the fake robot's true beam
makes, seen from above (``vision.render``).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from lasercal.collector.errors import DeviceError, RobotConnectionError, SessionError
from lasercal.collector.hardware.base import RobotAdapter
from lasercal.collector.sessions.cameras import OpenCVCamera
from lasercal.collector.sessions.capture import wait_still
from lasercal.collector.sessions.exposure import FakeExposure, readable_by, settle_exposure
from lasercal.collector.sessions.motion import MAX_STEP, confirm, plan_moves, preview
from lasercal.collector.sessions.store import CsvLog, cut_torn_line, write_atomic, write_atomic_bytes
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.session import Layout
from lasercal.solver.formats.table import csv_rows
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.whole import dump_yaml
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError
from lasercal.vision.exposure import exposure_advice
from lasercal.vision.render import LaserSpot, Photo, View, look_down, render

VALIDATION_FORMAT = "lasercal-validation/1"


def fake_view(centre_xy, plane_z: float, size=(1600, 1200), mm_per_px: float = 0.1) -> View:
    """A camera 800 mm above the table looking straight down at ``centre_xy`` (mm)."""
    return look_down(size=size, mm_per_px=mm_per_px, centre=tuple(centre_xy), height=800.0, z=plane_z)


# The fake camera of `validate`: 160 x 120 mm around the point (a nominal model's spots land up to ~30 mm
# off) at 0.2 mm/px, where the spot (sigma 2.5 px, 0.5 mm) is measured to ~0.01 mm; a quarter of the pixels
# of 0.1 mm/px, which made rendering, measuring and storing the photos 80 % of a run's time.
FAKE_VIEW_PX = (800, 600)
FAKE_MM_PER_PX = 0.2
PAPER = Photo.paper  # the blank sheet's brightness at exposure 1, of full scale


@dataclass(frozen=True)
class SpotLook:
    """How the fake laser spot looks: Gaussian sigma (px), peak (full scale), speckle contrast."""

    sigma: float = 2.5
    peak: float = 0.8
    speckle: float = 0.2


class FakeCamera(FakeExposure):
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
        (:class:`~collector.sessions.exposure.FakeExposure`); None: fixed at 1, as a device that refuses
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
        self._count = 0

    def photo(self) -> np.ndarray:
        spot, _ = self.robot.true_spot(self.plane_z)
        u, v = self.view.project(spot[:2])[0]
        self._count += 1
        lk, g = self.look, self.gain
        spot = LaserSpot(u, v, lk.sigma, lk.peak * g, lk.speckle)
        photo = Photo(self.view, (), (spot,), paper=PAPER * g, camera=self.sensor)
        return render(photo, seed=self.seed + self._count)

    def close(self) -> None:
        """Nothing to release."""


def measure_known_view(img: np.ndarray, name: str, view: View) -> tuple[np.ndarray, str | None]:
    """The spot of a photo taken through a known view, on the plane, (2,) mm, and the photo's
    exposure advice (one line, or None when the exposure is fine)."""
    spots, _ = detect_spots(img, name)
    exposure = exposure_advice(spots)
    return view.unproject(np.array([[spots[0].u, spots[0].v]]))[0], exposure and exposure.advice


def measure_with_markers(img: np.ndarray, name: str, markers, sheet=None) -> tuple[np.ndarray, str | None]:
    """The spot of a photo on the plane through the layout's fiducial markers (vision), (2,) mm, base frame
    (markers on a sheet: through the sheet's pose, eq. S1), and the photo's exposure advice (one line, or
    None)."""
    from lasercal.vision.measure import measure_photo  # imported here: only layouts with markers need it

    res = measure_photo(img, name, layout=markers)
    s = res.spots[0]
    xy = np.array([s.x_mm, s.y_mm])
    if sheet is not None:
        xy = sheet.to_base(xy[None], 0.0)[0, :2]
    return xy, res.exposure and res.exposure.advice


def make_camera(
    spec: str | None,
    cfg: dict,
    robot,
    layout: Layout,
    point: str,
    layout_path,
    sheet=None,
    paper=None,
    world=None,
):
    """The camera a validation photographs with, and how its photos are measured.

    Parameters
    ----------
    spec : str or None, ``fake``, an OpenCV device index, URL or image sequence (None: fake on the fake
        backend, else an error)
    cfg : dict, the validation settings (``backend``, ``seed``)
    robot : RobotAdapter (the fake camera renders the fake robot's true spot)
    layout : Layout (base frame); point : str, the validation point
    layout_path : the layout file, whose ``markers`` section (if any) maps real photos to mm
    sheet : SheetPose or None, the pose of a sheet layout's sheet (its markers' mm go through it)
    paper : collector.hardware.truesheet.PaperSheet or None, where the simulated table holds that sheet: the
        fake camera looks down at the point on it (:class:`~collector.sessions.spotcam.PaperTopCamera`), its
        spots read in the sheet's printed mm and go to the model's frame through ``sheet``
    world : collector.hardware.fakeworld.World or None, the simulated world's effects on the spot

    Returns
    -------
    (camera, measure): ``measure(img, name) -> ((2,) mm, exposure advice)`` or None when the photos can
    only be stored (a real camera and a layout without markers)
    """
    spec = spec or ("fake" if cfg["backend"] == "fake" else None)
    if spec == "fake":
        if cfg["backend"] != "fake":
            raise SessionError("--camera fake needs --backend fake (it renders the fake robot's true spot)")
        if paper is not None:  # a simulated sheet: the spot read in its printed mm, then the model's frame
            from lasercal.collector.sessions.spotcam import PaperTopCamera

            centre = sheet.from_base(layout.points[point][None])[0]
            cam = PaperTopCamera(robot, paper, centre, world, cfg["seed"], FAKE_VIEW_PX, FAKE_MM_PER_PX)

            def on_sheet(img, name):
                xy, advice = measure_known_view(img, name, cam.view)
                return sheet.to_base(xy[None], layout.plane_z)[0, :2], advice

            return cam, on_sheet
        view = fake_view(layout.points[point][:2], layout.plane_z, FAKE_VIEW_PX, FAKE_MM_PER_PX)
        camera = FakeCamera(robot, view, layout.plane_z, seed=cfg["seed"])
        return camera, lambda img, name: measure_known_view(img, name, view)
    if spec is None:
        raise SessionError(
            "validate needs --camera (an OpenCV device index, URL or image sequence) for a real robot"
        )
    from lasercal.vision.plane import load_markers

    markers = load_markers(layout_path)
    measure = None if markers is None else (lambda img, name: measure_with_markers(img, name, markers, sheet))
    return OpenCVCamera(int(spec) if spec.isdigit() else spec), measure


def validation_point(layout: Layout, point: str | None) -> str:
    """The point to validate at: ``point``, or the layout's first validation point."""
    point = point or (layout.validation[0] if layout.validation else None)
    if point is None:
        raise FormatError(
            layout.path, "the layout names no validation point: pass --point", field="validation"
        )
    if point not in layout.points:
        raise FormatError(
            layout.path,
            f"no point {point!r} to validate at (it has {', '.join(layout.points)})",
            field="points",
        )
    return point


SAME_POINT_MM = 1.0  # two reference points closer than this are the same point


def check_layout(layout: Layout, model: RobotModel, model_ref: str, point: str) -> None:
    """Cross-check the layout against the model and the session it was identified from.

    The validation point must not be a calibration point (a model is not validated on the
    data it was fitted to), the model's plane must be the layout's, and every point the
    model's session names must be where the layout has it.

    Raises
    ------
    FormatError
        Naming the layout file and the point or plane that disagrees.
    """
    p = layout.points[point]
    for nm in layout.calibration:
        if np.linalg.norm(layout.points[nm] - p) < SAME_POINT_MM:
            raise FormatError(
                layout.path,
                f"validation point {point} is calibration point {nm} (expected a point the model was not "
                "fitted to: pass --point)",
                field="points",
            )
    if model.plane_z is not None and abs(model.plane_z - layout.plane_z) > SAME_POINT_MM:
        raise FormatError(
            layout.path,
            f"plane z = {layout.plane_z:g} mm but the model {model_ref} was identified on z = "
            f"{model.plane_z:g} mm (expected the layout of the table the model was calibrated on)",
            field="plane",
        )
    from lasercal.collector.sessions.world import model_session

    session = model_session(model, model_ref)
    if session is not None:
        from lasercal.solver.formats.robots import load_yaml

        meta = load_yaml(session / "session.yaml")
        for nm, xyz in ((meta or {}).get("points") or {}).items():
            if xyz is None or str(nm) not in layout.points:
                continue
            if np.linalg.norm(np.asarray(xyz, dtype=float) - layout.points[str(nm)]) > SAME_POINT_MM:
                raise FormatError(
                    layout.path,
                    f"point {nm} is at {layout.points[str(nm)].tolist()} mm but the session the model was "
                    f"identified from ({session}) has it at {list(xyz)} mm (expected the same table)",
                    field=f"points.{nm}",
                )


@dataclass(frozen=True)
class ValidationResult:
    """Where a validation run wrote its table, and the spots it measured ((k, 2) mm, base frame).

    ``photos`` counts the rows written by this run, ``done`` those in the table (a resumed run
    adds to earlier ones) out of ``n`` planned configurations; ``failed`` the configurations of this
    run that gave no spot: a photo not measured, or an arm that did not come to rest (skipped).
    """

    path: Path
    photos: int
    spots: np.ndarray
    done: int = 0
    n: int = 0
    failed: int = 0

    @property
    def complete(self) -> bool:
        return self.done >= self.n

    def summary(self) -> str:
        """'60 of 60 configurations' or 'partial: 20 of 60 configurations'."""
        return f"{'' if self.complete else 'partial: '}{self.done} of {self.n} configurations"


def done_indices(path: Path) -> set[int]:
    """The configuration indices a validation.csv already holds (for --resume)."""
    rows = csv_rows(path)
    if not rows or rows[0][1][0] != "index":
        raise FormatError(path, "not a validation table (expected a header starting with 'index')", line=1)
    out = set()
    for ln, r in rows[1:]:
        try:
            out.add(int(r[0]))
        except ValueError:
            raise FormatError(path, f"index {r[0]!r} is not a whole number", line=ln, field="index") from None
    return out


@dataclass(frozen=True)
class ValidateOptions:
    """How a validation run behaves.

    Attributes
    ----------
    n : int, configurations
    seed : int, seed of the configurations the model computes
    guide : bool, guide the operator even where the backend could move the arm
    speed_threshold, hold, still_timeout, poll : standstill before each photo (rad/s, s, s, s)
    yes : bool, moves confirmed in advance (``--yes``); otherwise typed ``yes`` on a terminal
    max_step : float, rad, largest joint change in one commanded move (larger moves are split)
    keep_photos : int or None, write only the photos of the first k configurations (None: every one); the
        others are measured and not kept (their row's ``photo`` is empty): ``lasercal demo``'s 240 fake
        photos were 200 MB
    """

    n: int = 60
    seed: int = 0
    guide: bool = False
    speed_threshold: float = 0.005
    hold: float = 0.5
    still_timeout: float = 30.0
    poll: float = 1 / 64
    yes: bool = False
    max_step: float = MAX_STEP
    keep_photos: int | None = None


def run_validation(
    folder,
    model: RobotModel,
    model_ref: str,
    layout: Layout,
    point: str,
    robot: RobotAdapter,
    camera,
    opts: ValidateOptions,
    trigger=None,
    measure=None,
    out=sys.stdout,
    meta_extra: dict | None = None,
    resume: bool = False,
    confirm_moves: bool = True,
) -> ValidationResult:
    """Photograph the spot at N configurations ``model`` computes for ``point``; write validation.csv.

    Parameters
    ----------
    folder : path of a new folder: validation.yaml, validation.csv, photos/NNNN.png
    model : RobotModel, the model under test (nominal or identified)
    model_ref : str, how validation.yaml names it
    layout : Layout
    point : str, the validation point's name (see :func:`validation_point`)
    robot : RobotAdapter, connected by this function and closed when it returns
    camera : OpenCVCamera or FakeCamera
    opts : ValidateOptions
    trigger : Trigger, needed when the operator guides the arm
    measure : callable(img, name) -> ((2,) mm, exposure advice or None), or None to leave x_mm, y_mm empty
    out : text stream
    meta_extra : dict, more keys for validation.yaml (the CLI stores what ``--resume`` needs)
    resume : bool, continue the run in ``folder``: configurations already photographed are skipped
    confirm_moves : bool, ask (:func:`collector.sessions.motion.confirm`) before the first move; off only
        for the simulated robot

    A Ctrl-C or a lost link stops the arm; the table keeps every photo taken (each written
    atomically), and ``resume`` continues where it stopped.

    Returns
    -------
    ValidationResult
    """
    p = layout.points[point]
    folder = Path(folder)
    if not resume and (folder / "validation.csv").exists():
        raise SessionError(f"{folder} already holds a validation run: resume it with --resume {folder}")
    planned = layout.aim_at(model, point, opts.n, np.random.default_rng(opts.seed))
    guided = opts.guide or not robot.can_move
    if guided and trigger is None:
        raise DeviceError(
            f"the {robot.name} backend cannot move the arm: the operator guides it, so a trigger is needed"
        )
    if resume:  # a row a kill tore is cut off (then the log goes on after the last whole row)
        cut_torn_line(folder / "validation.csv")
    done = done_indices(folder / "validation.csv") if resume else set()
    todo = [i for i in range(len(planned)) if i not in done]
    meta = {
        "format": VALIDATION_FORMAT,
        "model": model_ref,
        "point": {"name": point, "xyz": [float(v) for v in p]},
        "plane": {"z": float(layout.plane_z)},
        "n": opts.n,
        "seed": opts.seed,
        "backend": robot.name,
        "camera": camera.name,
        "simulated": "fake" in (robot.name, camera.name),  # the report says simulated or measured
        "motion": "guided by the operator" if guided else "moved by the backend",
        "units": {"q": "rad", "x_mm": "mm", "y_mm": "mm", "q_dev": "rad"},
        "columns": {
            "q1..qN": "measured joint positions when the photo was taken",
            "photo": "relative to this folder (empty: measured, not kept)",
            "x_mm, y_mm": "the spot on the plane, base frame (empty: not measured -- no markers)",
            "q_dev": "largest joint deviation from the configuration the model computed",
        },
        **(meta_extra or {}),
    }
    plan = None
    robot.connect()
    try:  # preview and confirmation before the first file and the first move
        if not guided and todo:
            plan = plan_moves(robot.read().q, planned[todo], model, opts.max_step)
            out.write(preview(plan))
            if confirm_moves:
                confirm(plan, opts.yes, out=out)
    except BaseException:
        robot.close()
        camera.close()
        raise
    if not resume:
        (folder / "photos").mkdir(parents=True, exist_ok=True)
        write_atomic(folder / "validation.yaml", dump_yaml(meta, sort_keys=False, width=120))
    header = ["index"] + [f"q{j + 1}" for j in range(model.n)] + ["photo", "x_mm", "y_mm", "q_dev"]
    log = CsvLog(
        folder / "validation.csv",
        header,
        [
            f"lasercal validation of {model_ref} at {point}: q rad, x_mm/y_mm mm "
            f"(plane z = {layout.plane_z:g} mm), q_dev rad; see validation.yaml"
        ],
        resume=resume,
    )
    w = out.write
    photos, spots, failed, settled = 0, [], 0, False
    if resume:
        w(f"resuming {folder}: {len(done)} of {opts.n} configurations done, {len(todo)} to go\n")
    try:
        for k, i in enumerate(todo):
            q = planned[i]
            if guided:
                robot.prompt_configuration(q)
                now = robot.read().q
                w(
                    f"\nconfiguration {i + 1}/{opts.n}: guide the arm to q = {np.round(q, 3).tolist()} rad\n"
                    f"  now off by {np.round(q - now, 3).tolist()} rad   [{trigger.hint}]\n"
                )
                cmd = trigger.wait()
                if cmd == "quit":
                    w(f"stopped after {photos} photos: {log.path}\n")
                    break
                if cmd == "discard":
                    w(f"configuration {i + 1} skipped\n")
                    continue
            else:
                for step in plan.steps[plan.target_of == k]:
                    robot.move_to(step)
            state, peak = wait_still(robot, opts.speed_threshold, opts.hold, opts.still_timeout, opts.poll)
            if state is None:
                failed += 1
                w(
                    f"configuration {i + 1}: the arm did not come to rest (max |dq| {peak:.4f} rad/s): "
                    "skipped\n"
                )
                continue
            # the exposure is settled on the first photo, with the laser on the point
            img = camera.photo() if settled else settle_exposure(camera, readable_by(measure))
            settled = True
            name = f"photos/{i:04d}.png" if opts.keep_photos is None or i < opts.keep_photos else ""
            if name:
                ok, png = cv2.imencode(".png", img)
                if not ok:
                    raise DeviceError(f"cannot encode photo {name}")
                write_atomic_bytes(folder / name, png.tobytes())  # a kill leaves no truncated photo
            row = {
                "index": str(i),
                **{f"q{j + 1}": v for j, v in enumerate(state.q)},
                "photo": name,
                "q_dev": float(np.abs(state.q - q).max()),
            }
            msg = f"photo {i + 1}/{opts.n}: {name or 'not kept'}"
            if measure is not None:
                try:
                    xy, advice = measure(img, name)
                except VisionError as e:  # one unreadable photo must not end the run: it stays on disk
                    msg += f", not measured ({e})"
                    failed += 1
                else:
                    row.update(x_mm=float(xy[0]), y_mm=float(xy[1]))
                    spots.append(xy)
                    msg += f", spot {np.hypot(*(xy - p[:2])):.2f} mm from {point}"
                    if advice:  # said while the photos are taken, so the next ones can be better
                        msg += f"; exposure: {advice}"
            log.append(row)
            photos += 1
            w(msg + "\n")
    except (RobotConnectionError, KeyboardInterrupt) as e:
        robot.stop()
        total = len(done) + photos
        where = (
            f"partial: {total} of {opts.n} configurations in {log.path}; "
            f"continue with lasercal validate --resume {folder}"
        )
        if isinstance(e, KeyboardInterrupt):
            w(f"\ninterrupted: the arm was stopped; {where}\n")
            raise
        raise RobotConnectionError(f"{e}; {where}") from None
    finally:
        log.close()
        robot.close()
        camera.close()
    return ValidationResult(
        log.path, photos, np.array(spots).reshape(-1, 2), len(done) + photos, opts.n, failed
    )
