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
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from lasercal.collector.errors import DeviceError, RobotConnectionError, SessionError
from lasercal.collector.hardware import mujoco_camera, top_camera
from lasercal.collector.hardware.base import RobotAdapter
from lasercal.collector.hardware.cameras import OpenCVCamera
from lasercal.collector.sessions.coaching import StateStream
from lasercal.collector.sessions.exposure import readable_by, settle_exposure
from lasercal.collector.sessions.motion import MAX_STEP, confirm, plan_moves, preview
from lasercal.collector.sessions.photos import (
    ALL_PNG,
    PhotoPolicy,
    estimate_line,
    start_estimate_line,
    written_line,
)
from lasercal.collector.sessions.standstill import wait_still
from lasercal.collector.sessions.state import ACTIONS, SessionState
from lasercal.collector.sessions.store import CsvLog, cut_torn_line, write_atomic, write_atomic_bytes
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.session import Layout
from lasercal.solver.formats.table import csv_rows
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.whole import dump_yaml
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError
from lasercal.vision.exposure import exposure_advice
from lasercal.vision.render import View

VALIDATION_FORMAT = "lasercal-validation/1"


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
        xy = sheet.to_base(on_curled_paper(xy, res.plane.H, img.shape, markers, sheet)[None], 0.0)[0, :2]
    return xy, res.exposure and res.exposure.advice


def on_curled_paper(xy: np.ndarray, H: np.ndarray, shape: tuple, markers, sheet) -> np.ndarray:
    """Where on a curled sheet (the model's eq. S6) the spot lies whose photo, mapped through the markers'
    homography ``H``, reads ``xy`` (2,) mm in the layout's frame: eq. S8 undone from where the photo's
    markers put the camera (eq. V2). ``xy`` itself on a flat sheet, or where the markers cannot tell where
    the camera stands (a square-on view, whose parallax at the sheet's middle is small)."""
    from lasercal.solver.kinematics.parallax import unparallaxed
    from lasercal.vision.plane import camera_eye

    curl = sheet.curl
    eye = camera_eye(H, (shape[1], shape[0])) if np.any(curl) else None
    if eye is None:
        return xy
    corners = np.concatenate([np.asarray(c, dtype=float) for c in markers.corners.values()])
    return unparallaxed(xy, eye, curl, corners)


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
    paper : collector.worlds.truesheet.PaperSheet or None, where the simulated table holds that sheet: the
        fake camera looks down at the point on it (:class:`~collector.worlds.cameras.PaperTopCamera`), its
        spots read in the sheet's printed mm and go to the model's frame through ``sheet``
    world : collector.worlds.fakeworld.World or None, the simulated world's effects on the spot

    Returns
    -------
    (camera, measure): ``measure(img, name) -> ((2,) mm, exposure advice)`` or None when the photos can
    only be stored (a real camera and a layout without markers)
    """
    spec = spec or {"fake": "fake", "mujoco": "mujoco"}.get(cfg["backend"])
    if spec == "fake":
        if cfg["backend"] != "fake":
            raise SessionError("--camera fake needs --backend fake (it renders the fake robot's true spot)")
        if paper is not None:  # a simulated sheet: the spot read in its printed mm, then the model's frame
            centre = sheet.from_base(layout.points[point][None])[0]
            cam = top_camera(robot, centre, layout.plane_z, cfg["seed"], paper, world)

            def on_sheet(img, name):
                xy, advice = measure_known_view(img, name, cam.view)
                return sheet.to_base(xy[None], layout.plane_z)[0, :2], advice

            return cam, on_sheet
        camera = top_camera(robot, layout.points[point][:2], layout.plane_z, cfg["seed"])
        return camera, lambda img, name: measure_known_view(img, name, camera.view)
    if spec is None:
        raise SessionError(
            "validate needs --camera (an OpenCV device index, URL or image sequence) for a real robot"
        )
    from lasercal.vision.plane import load_markers

    markers = load_markers(layout_path)
    measure = None if markers is None else (lambda img, name: measure_with_markers(img, name, markers, sheet))
    if spec == "mujoco":  # the MuJoCo world's camera, measured as a real camera's photos are
        return mujoco_camera(robot), measure
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
            others = [
                k
                for k in layout.points
                if all(
                    np.linalg.norm(layout.points[c] - layout.points[k]) >= SAME_POINT_MM
                    for c in layout.calibration
                )
            ]
            hint = f", e.g. --point {others[0]}" if others else ""
            raise FormatError(
                layout.path,
                f"validation point {point} is calibration point {nm} (expected a point the model was not "
                f"fitted to{hint})",
                field="points",
            )
    if model.plane_z is not None and abs(model.plane_z - layout.plane_z) > SAME_POINT_MM:
        raise FormatError(
            layout.path,
            f"plane z = {layout.plane_z:g} mm but the model {model_ref} was identified on z = "
            f"{model.plane_z:g} mm (expected the layout of the table the model was calibrated on)",
            field="plane",
        )
    from lasercal.collector.sessions.sheetframe import model_session

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


def validation_commands(
    layout: Layout, model: RobotModel, model_ref, point: str, n: int, seed: int
) -> np.ndarray:
    """The configurations a validation commands at ``point`` (n, N) rad: ``n`` diverse in-limit poses whose
    beam meets the point under the model (the aiming IK, seed ``seed``), as the robot's encoders must read
    them -- under the model's robot effects (a compliance, an eccentricity) the true pose is the aimed one
    (:func:`solver.control.correct.command_angles`, their torques the fit's gravity model's), as ``correct``
    commands a goal; ``validate`` and ``configurations`` both call this."""
    from lasercal.solver.control.correct import command_angles, joint_effect
    from lasercal.solver.control.nominal import gravity_robot
    from lasercal.solver.kinematics.effects import extension_from_model

    q = layout.aim_at(model, point, n, np.random.default_rng(seed))
    ext = extension_from_model(model.extensions, model_ref, model.n)
    if ext is None:
        return q
    joint_effect(ext)
    return command_angles(model, ext, q, gravity_robot(model, model_ref))


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
    photos : PhotoPolicy, which photos are written (``first``: the run's first and every one not measured)
        and how; a run whose photos are not measured (no markers) keeps them all
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
    photos: PhotoPolicy = ALL_PNG


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
    state: SessionState | None = None,
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
    out : text stream (None: only ``state``'s listeners see the lines)
    meta_extra : dict, more keys for validation.yaml (the CLI stores what ``--resume`` needs)
    resume : bool, continue the run in ``folder``: configurations already photographed are skipped
    confirm_moves : bool, ask (:func:`collector.sessions.motion.confirm`) before the first move; off only
        for the simulated robot
    state : SessionState or None, what the run is doing, for the terminal and the live view (None: a new
        one that writes to ``out``)

    A Ctrl-C or a lost link stops the arm; the table keeps every photo taken (each written
    atomically), and ``resume`` continues where it stopped.

    Returns
    -------
    ValidationResult
    """
    state = SessionState("validation", out) if state is None else state
    run = ValidationRun(folder, model, model_ref, layout, point, robot, camera, opts, trigger, measure, state)
    return run.run(meta_extra, resume, confirm_moves)


class ValidationRun:
    """A validation run as a state machine, as :class:`~collector.sessions.capture.CaptureRun`:
    ``prepare`` (plan, preview and confirmation, files) -> per configuration ``reach`` (moved there, or
    guided and triggered) -> ``settle`` -> ``photograph`` (measure, keep, the row) -> ... -> the end.
    Parameters as :func:`run_validation`'s."""

    def __init__(self, folder, model, model_ref, layout, point, robot, camera, opts, trigger, measure, state):
        self.folder, self.model, self.model_ref, self.layout = Path(folder), model, model_ref, layout
        self.point, self.robot, self.camera, self.opts = point, robot, camera, opts
        self.trigger, self.measure, self.state = trigger, measure, state
        self.p = layout.points[point]
        self.guided = opts.guide or not robot.can_move
        self.photos, self.spots, self.failed, self.settled = 0, [], 0, False
        self.k = 0  # the next of the configurations to do (an index into ``todo``)
        # a photo nobody measures is the only record of its spot: kept whatever --photos says
        self.policy = opts.photos if measure is not None else replace(opts.photos, keep="all")

    def say(self, text: str) -> None:
        self.state.say(text)

    def show_progress(self) -> None:
        done = len(self.done) + self.photos
        self.state.update(progress=[{"name": self.point, "done": done, "want": self.opts.n}])

    def run(self, meta_extra, resume: bool, confirm_moves: bool) -> ValidationResult:
        folder, opts, robot, camera = self.folder, self.opts, self.robot, self.camera
        if not resume and (folder / "validation.csv").exists():
            raise SessionError(f"{folder} already holds a validation run: resume it with --resume {folder}")
        self.planned = validation_commands(
            self.layout, self.model, self.model_ref, self.point, opts.n, opts.seed
        )
        if self.guided and self.trigger is None:
            raise DeviceError(
                f"the {robot.name} backend cannot move the arm: the operator guides it, so a trigger is "
                "needed"
            )
        if resume:  # a row a kill tore is cut off (then the log goes on after the last whole row)
            cut_torn_line(folder / "validation.csv")
        self.done = done_indices(folder / "validation.csv") if resume else set()
        self.todo = [i for i in range(len(self.planned)) if i not in self.done]
        self.state.phase("setup", f"validating {self.model_ref} at {self.point}")
        self.state.update(
            target={"xy": [float(v) for v in self.markers_xy()], "tol_mm": 1.0, "label": self.point}
        )
        self.show_progress()
        self.plan = None
        robot.connect()
        try:  # preview and confirmation before the first file and the first move
            if not self.guided and self.todo:
                self.plan = plan_moves(robot.read().q, self.planned[self.todo], self.model, opts.max_step)
                self.say(preview(self.plan))
                if confirm_moves:
                    self.state.phase(
                        "confirm", "confirm the moves in the terminal: the page cannot", ("stop",)
                    )
                    confirm(self.plan, opts.yes, out=StateStream(self.state))
        except BaseException:
            robot.close()
            camera.close()
            raise
        self.log = self.open_files(meta_extra, resume)
        policy = self.policy
        self.say(
            f"every photo {'is measured at once (validation.csv) and ' if self.measure else ''}kept as the "
            f"options say: {policy.words()} ({policy.choices()})\n"
        )
        kept = len(self.todo) if opts.keep_photos is None else min(len(self.todo), opts.keep_photos)
        need = start_estimate_line(policy, kept, 1)
        if need:
            self.say(need + "\n")
        if resume:
            self.say(
                f"resuming {folder}: {len(self.done)} of {opts.n} configurations done, {len(self.todo)} to "
                "go\n"
            )
        step = self.reach if self.todo else None
        try:
            while step is not None:
                step = step()
        except (RobotConnectionError, KeyboardInterrupt) as e:
            robot.stop()
            total = len(self.done) + self.photos
            where = (
                f"partial: {total} of {opts.n} configurations in {self.log.path}; "
                f"continue with lasercal validate --resume {folder}"
            )
            self.state.end(where, "stopped")
            if isinstance(e, KeyboardInterrupt):
                moved = "" if self.guided else "the arm was stopped; "  # a hand-guided arm is the operator's
                self.say(f"\ninterrupted: {moved}{where}\n")
                raise
            raise RobotConnectionError(f"{e}; {where}") from None
        finally:
            self.log.close()
            robot.close()
            camera.close()
        self.say(written_line(folder) + "\n")
        spots, done = np.array(self.spots).reshape(-1, 2), len(self.done) + self.photos
        res = ValidationResult(self.log.path, self.photos, spots, done, opts.n, self.failed)
        if not self.state.data["ended"]:
            self.state.end(f"{res.summary()} in {res.path}")
        return res

    def markers_xy(self) -> np.ndarray:
        """The validation point in the frame of the layout file's markers (a sheet's own), where the page
        draws its target: the layout as loaded (the one the run is given is in the base frame)."""
        from lasercal.solver.formats.session import load_layout

        return load_layout(self.layout.path).points[self.point][:2]

    def open_files(self, meta_extra, resume: bool) -> CsvLog:
        folder, layout, model, opts, p = self.folder, self.layout, self.model, self.opts, self.p
        meta = {
            "format": VALIDATION_FORMAT,
            "model": self.model_ref,
            "point": {"name": self.point, "xyz": [float(v) for v in p]},
            "plane": {"z": float(layout.plane_z)},
            "n": opts.n,
            "seed": opts.seed,
            "backend": self.robot.name,
            "camera": self.camera.name,
            "simulated": "fake"
            in (self.robot.name, self.camera.name),  # the report says simulated or measured
            "motion": "guided by the operator" if self.guided else "moved by the backend",
            "units": {"q": "rad", "x_mm": "mm", "y_mm": "mm", "q_dev": "rad"},
            "columns": {
                "q1..qN": "measured joint positions when the photo was taken",
                "photo": "relative to this folder (empty: measured, not kept)",
                "x_mm, y_mm": "the spot on the plane, base frame (empty: not measured -- no markers)",
                "q_dev": "largest joint deviation from the configuration the model computed",
            },
            **(meta_extra or {}),
        }
        if not resume:
            (folder / "photos").mkdir(parents=True, exist_ok=True)
            write_atomic(folder / "validation.yaml", dump_yaml(meta, sort_keys=False, width=120))
        header = ["index"] + [f"q{j + 1}" for j in range(model.n)] + ["photo", "x_mm", "y_mm", "q_dev"]
        comment = (
            f"lasercal validation of {self.model_ref} at {self.point}: q rad, x_mm/y_mm mm "
            f"(plane z = {layout.plane_z:g} mm), q_dev rad; see validation.yaml"
        )
        return CsvLog(folder / "validation.csv", header, [comment], resume=resume)

    def reach(self):
        """The next configuration: the arm moved there, or the operator guides it and triggers."""
        if self.k >= len(self.todo):
            return None
        if self.state.stop_asked():  # the page's stop, asked in any phase before
            return self.stopped()
        i, opts = self.todo[self.k], self.opts
        q = self.planned[i]
        if self.guided:
            self.robot.prompt_configuration(q)
            now = self.robot.read().q
            line = f"configuration {i + 1}/{opts.n}: guide the arm to q = {np.round(q, 3).tolist()} rad"
            self.state.phase("aiming", line, ACTIONS)
            self.say(f"\n{line}\n  now off by {np.round(q - now, 3).tolist()} rad   [{self.trigger.hint}]\n")
            cmd = self.trigger.wait()
            if cmd == "quit":
                return self.stopped()
            if cmd == "discard":
                self.say(f"configuration {i + 1} skipped\n")
                self.k += 1
                return self.reach
        else:
            steps = self.plan.steps[self.plan.target_of == self.k]
            self.state.phase("moving", f"moving to configuration {i + 1}/{opts.n}", ACTIONS[2:])
            for step in steps:
                if self.state.stop_asked():  # between two steps: the arm stays where it is
                    return self.stopped()
                self.robot.move_to(step)
        return self.settle

    def stopped(self):
        """The operator stopped the run (the terminal's quit, or the page's stop at a safe point)."""
        self.say(f"stopped after {self.photos} photos: {self.log.path}\n")
        self.state.end(f"stopped after {self.photos} photos: {self.log.path}", "stopped")
        return None

    def settle(self):
        opts, i = self.opts, self.todo[self.k]
        self.state.phase("settling", "waiting for the arm to be still", ACTIONS[2:])
        state, peak = wait_still(self.robot, opts.speed_threshold, opts.hold, opts.still_timeout, opts.poll)
        if self.state.stop_asked():  # nothing photographed after a stop
            return self.stopped()
        if state is None:
            self.failed += 1
            msg = f"configuration {i + 1}: the arm did not come to rest (max |dq| {peak:.4f} rad/s): skipped"
            self.say(msg + "\n")
            self.state.problem(msg)
            self.k += 1
            return self.reach
        self.still = state
        return self.photograph

    def photograph(self):
        """Photograph the spot, measure it from the photo in memory, keep the photo as the options say,
        append the row."""
        opts, policy, i, state, p = self.opts, self.policy, self.todo[self.k], self.still, self.p
        self.state.phase("photo", f"photographing configuration {i + 1}/{opts.n}")
        q = self.planned[i]
        # the exposure is set with the laser on the point, and again at each photo until a spot was read
        # unclipped (an advice to lower it is a clipped spot): one photo off the markers does not fix it
        first = self.photos == 0
        img = self.camera.photo() if self.settled else settle_exposure(self.camera, readable_by(self.measure))
        self.settled |= self.measure is None  # nothing to read the spot by: set once, on the first photo
        name = f"photos/{i:04d}.{policy.fmt}"
        row = {"index": str(i), **{f"q{j + 1}": v for j, v in enumerate(state.q)}}
        seen, last = "", {"point": self.point, "number": i + 1, "measured": False}
        if self.measure is not None:  # measured from the photo in memory, kept or not
            try:
                xy, advice = self.measure(img, name)
            except VisionError as e:  # one unreadable photo must not end the run: it stays on disk
                seen = f", not measured ({e})"
                self.failed += 1
                self.state.problem(f"configuration {i + 1}: the spot could not be measured ({e})", img)
            else:
                row.update(x_mm=float(xy[0]), y_mm=float(xy[1]))
                self.settled = self.settled or not (advice and "spot clipped over" in advice)
                self.spots.append(xy)
                err = float(np.hypot(*(xy - p[:2])))
                seen = f", spot {err:.2f} mm from {self.point}"
                last.update(error_mm=err)
                if advice:  # said while the photos are taken, so the next ones can be better
                    seen += f"; exposure: {advice}"
        keep = opts.keep_photos is None or i < opts.keep_photos
        keep &= policy.kept(len(self.done) + self.photos == 0, "x_mm" in row)
        data = policy.encode(img, name) if keep or first else b""
        if keep:
            write_atomic_bytes(self.folder / name, data)  # a kill leaves no truncated photo
        if first and policy.keep != "none":
            self.say(estimate_line(policy, len(data), len(self.todo), 1) + "\n")
        row.update(photo=name if keep else "", q_dev=float(np.abs(state.q - q).max()))
        self.log.append(row)
        self.photos += 1
        self.say(f"photo {i + 1}/{opts.n}: {name if keep else 'not kept'}{seen}\n")
        self.state.update(last=last)
        self.show_progress()
        self.k += 1
        return self.reach
