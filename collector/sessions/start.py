"""Starting a capture or validation session from its settings: the models, devices and store it runs with.

The devices open before the session folder is written or reopened, so a device that fails leaves
nothing to clean up; what the session then does is :func:`sessions.capture.run_capture` or
:func:`sessions.validate.run_validation`, called by the ``run`` method of what is started here.
"""

from __future__ import annotations

import sys
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

from lasercal.collector.hardware import (
    SIMULATED,
    draw_world,
    fake_table,
    make_rangefinder,
    make_robot,
    no_effects,
    recorded_world,
    validation_world,
)
from lasercal.collector.hardware.base import RobotAdapter
from lasercal.collector.hardware.triggers import AutoTrigger, Trigger, make_trigger
from lasercal.collector.sessions.anywhere import session_layout_file
from lasercal.collector.sessions.capture import CaptureOptions, CaptureResult, new_session, run_capture
from lasercal.collector.sessions.coaching import StateStream, aimed_layout, session_coach
from lasercal.collector.sessions.motion import MAX_STEP, confirmable
from lasercal.collector.sessions.photos import PhotoPolicy
from lasercal.collector.sessions.settings import CaptureSettings, ValidateSettings
from lasercal.collector.sessions.sheetframe import check_same_frame, model_session
from lasercal.collector.sessions.spotcam import BESIDE_MM, capture_camera
from lasercal.collector.sessions.state import EitherTrigger, SessionState
from lasercal.collector.sessions.store import CaptureStore
from lasercal.solver.errors import FormatError, LasercalError
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Layout, load_layout
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.sheet import SheetPose

if TYPE_CHECKING:  # annotations only: sessions.validate loads OpenCV, which a capture does not need
    from lasercal.collector.sessions.validate import ValidateOptions, ValidationResult


@dataclass(frozen=True)
class CaptureGuide:
    """How the operator is guided through a capture session.

    Attributes
    ----------
    auto : bool, the simulated operator triggers too (fake backend only) and flagged captures are discarded
    auto_pace : float, with ``auto``: real seconds per capture, to watch, s
    move : bool, a backend that can move takes the arm to the coach's suggested poses first
    coach : bool, a status block, suggested poses and the stopping rule after each capture
    until_mm : float or None, stop once the coach predicts at most this error at the validation points, mm
    yes : bool, with ``move``: the moves are confirmed in advance; otherwise typed ``yes`` on a terminal
    max_step : float, largest joint change of one commanded move, rad
    """

    auto: bool = False
    auto_pace: float = 0.0
    move: bool = False
    coach: bool = True
    until_mm: float | None = None
    yes: bool = False
    max_step: float = MAX_STEP


@dataclass(frozen=True)
class StartedCapture:
    """A capture session with its devices open and its folder written (new) or reopened (resumed).

    Attributes
    ----------
    settings : CaptureSettings
    store : CaptureStore, ``recovered`` says whether a resume cut off a torn last line
    robot : RobotAdapter; trigger : Trigger; rangefinder : the rangefinder or None
    nominal : RobotModel, the robot the session names
    opts : CaptureOptions
    hint : str, the command that resumes the session
    coach : bool, run the capture coach
    camera : the camera that photographs each capture, or None; measure : how its photos are measured
    spots : dict name -> (k, 3) array or None, ``--aim anywhere``: the spots of each point's cell the
        coach may plan, layout frame, mm (:func:`aim_cells`)
    """

    settings: CaptureSettings
    store: CaptureStore
    robot: RobotAdapter
    trigger: Trigger
    rangefinder: object
    nominal: RobotModel
    opts: CaptureOptions
    hint: str
    coach: bool
    camera: object = None
    measure: object = None
    spots: dict | None = None

    def run(self, out=sys.stdout, view=None) -> CaptureResult:
        """Run the session (:func:`run_capture`) on screen ``out``; close the store and devices after.

        Parameters
        ----------
        out : text stream, the operator's screen
        view : collector.view.ViewOptions or None, serve the live view while the session runs

        Returns
        -------
        CaptureResult
        """
        state = SessionState("capture", out)
        try:
            with ExitStack() as stack:
                try:
                    camera = stack.enter_context(session_view(state, view, self.camera, self.layout_file()))
                except BaseException:  # e.g. the view's port taken: a new session, still empty, is undone
                    self.abandon()
                    raise
                return self._run(state, camera, view is not None)
        finally:
            self.store.close()
            if self.camera is not None:
                self.camera.close()
            self.trigger.close()
            if self.rangefinder is not None:
                self.rangefinder.close()

    def layout_file(self):
        """The layout file the session's markers are in."""
        cfg, folder = self.settings.cfg, self.settings.folder
        return session_layout_file(cfg, folder) if self.settings.resume else self.settings.layout_path

    def abandon(self) -> None:
        """A new session that could not start, still empty, leaves nothing behind."""
        self.store.close()
        if not self.settings.resume and not self.store.point:
            self.store.remove_empty()

    def _run(self, state, camera, viewed: bool) -> CaptureResult:
        cfg, layout = self.settings.cfg, self.settings.layout
        state.phase("setup", "the coach designs the session")
        try:
            # Built here, not at start: the coach's design takes a while, after the resume is announced.
            coach = None
            if self.coach:
                sheet = layout.sheet if layout.frame == "sheet" else None
                # where the operator aims: beside the crosses in a camera session, or anywhere in their cells
                aimed = aimed_layout(layout, self.store.meta.get("aim_offset")).in_base()
                anywhere = None
                if self.spots is not None:
                    anywhere = {k: layout.sheet.to_base(v, layout.plane_z) for k, v in self.spots.items()}
                coach = session_coach(self.store, self.nominal, aimed, cfg, sheet, anywhere)
        except BaseException:  # e.g. a layout point out of reach: a new session, still empty, is undone
            self.abandon()
            raise
        real = cfg["backend"] not in SIMULATED
        return run_capture(
            self.store,
            self.robot,
            EitherTrigger(self.trigger, state) if viewed else self.trigger,
            self.nominal,
            self.opts,
            None,
            self.rangefinder,
            self.hint,
            coach,
            real,
            camera,
            self.measure,
            state,
        )


def start_capture(settings: CaptureSettings, guide: CaptureGuide) -> StartedCapture:
    """Open the devices of a capture session, then create or reopen its folder.

    Parameters
    ----------
    settings : CaptureSettings (see :func:`sessions.settings.capture_settings`)
    guide : CaptureGuide

    Returns
    -------
    StartedCapture

    Raises
    ------
    LasercalError
        ``auto`` off the fake backend; ``move`` without the coach or on a backend that cannot move.
    MotionRefused
        ``move`` on a real robot whose moves cannot be confirmed (no ``yes`` and no terminal).
    """
    cfg, layout = settings.cfg, settings.layout
    if guide.auto and cfg["backend"] not in SIMULATED:
        raise LasercalError(
            "--auto needs --backend fake or mujoco (only the simulated operator can trigger by itself)"
        )
    nominal = load_model(cfg["robot"])
    # a resumed session goes on in the world it recorded (its draws, the camera's calibration)
    world = (
        recorded_world(settings.folder)
        if settings.resume
        else draw_world(cfg.get("effects"), cfg["seed"], layout)
    )
    camera_spec = cfg.get("camera")
    layout_file = session_layout_file(cfg, settings.folder) if settings.resume else settings.layout_path
    spots = aim_cells(cfg, guide, layout, layout_file, settings.resume)
    beside = BESIDE_MM if camera_spec and spots is None else (0.0, 0.0)
    # a sheet's points where its placement says: the simulated operator's table (as printed, on the sheet's
    # true surface; beside the crosses with a camera that aims at them), the coach's aim
    points, place = fake_table(layout, world, beside)
    robot = make_robot(
        cfg,
        nominal,
        layout.in_base(),
        cfg["per_point"],
        points=points,
        repeat_sigma=world.repeat_sigma,
        place=place,
        placement=layout.sheet if layout.frame == "sheet" else None,
        printed=layout.frame == "sheet",
    )
    camera, measure = capture_camera(camera_spec, cfg, robot, layout, layout_file, world)
    rangefinder = make_rangefinder(cfg, robot, layout.plane_z)
    trigger = AutoTrigger(guide.auto_pace) if guide.auto else make_trigger(cfg["trigger"], robot)
    if guide.move:  # refused before the session folder exists
        if not guide.coach:
            raise LasercalError("--guide move moves the arm to the coach's suggestions: drop --no-coach")
        if not robot.can_move:
            raise LasercalError(
                f"--guide move: the {robot.name} backend cannot move the arm (use --guide hand)"
            )
        if cfg["backend"] not in SIMULATED:
            confirmable(guide.yes, what="to the suggested poses ")
    if settings.resume:
        store = CaptureStore.open(settings.folder)
    else:
        store = new_session(
            settings.folder, cfg, layout, settings.layout_path, robot, nominal, rangefinder, camera, world
        )
    opts = CaptureOptions(
        cfg["per_point"],
        cfg["speed_threshold"],
        cfg["hold"],
        auto_discard=guide.auto,
        until_mm=guide.until_mm,
        move=guide.move,
        yes=guide.yes,
        max_step=guide.max_step,
        photos=PhotoPolicy.of(cfg),
    )
    hint = (
        f"lasercal capture --resume {store.folder}"
        + (" --auto" if guide.auto else "")
        + (" --guide move" if guide.move else "")
    )
    return StartedCapture(
        settings, store, robot, trigger, rangefinder, nominal, opts, hint, guide.coach, camera, measure, spots
    )


def aim_cells(cfg: dict, guide: CaptureGuide, layout, layout_file, resume: bool) -> dict | None:
    """Where a session's coach may plan its spots: ``cfg['aim']`` 'anywhere' (the default of a new camera
    session with the coach on a sheet ``lasercal sheet`` printed) gives each point's cell of measurable
    spots (:func:`sessions.anywhere.cells`), 'cross' None: on (or beside) the points. A new session without
    ``aim`` gets it here (it is stored: a resume keeps it).

    Raises
    ------
    LasercalError
        'anywhere' without a camera or the coach, or on a layout that is no printed sheet.
    """
    from lasercal.collector.errors import SessionError
    from lasercal.collector.sessions.anywhere import cells

    camera = cfg.get("camera")
    if not resume and cfg.get("aim") is None:  # a measured spot need not be on its cross
        cfg["aim"] = "cross"
        if camera and guide.coach:
            try:
                spots = cells(layout, layout_file)
            except SessionError:  # no printed sheet: its blank paper is unknown
                return None
            cfg["aim"] = "anywhere"
            return spots
    if cfg.get("aim") != "anywhere":
        return None
    if not (camera and guide.coach):
        raise LasercalError(
            "--aim anywhere: the coach plans each spot and the camera measures where it lands: it needs "
            "--camera and the coach (drop --no-coach), or use --aim cross"
        )
    return cells(layout, layout_file)


@dataclass(frozen=True)
class StartedValidation:
    """A validation run with its models checked and its devices open.

    Attributes
    ----------
    settings : ValidateSettings
    model : RobotModel, the model under test
    layout : Layout; point : str, the validation point
    robot : RobotAdapter; camera : the camera; measure : how its photos are measured, or None
    trigger : Trigger or None (None: the robot moves itself to each configuration)
    opts : ValidateOptions
    world : SimulatedWorld or None, the fake backend's true robot and sheet on a sheet layout
    """

    settings: ValidateSettings
    model: RobotModel
    layout: Layout
    point: str
    robot: RobotAdapter
    camera: object
    measure: object
    trigger: Trigger | None
    opts: ValidateOptions
    world: object | None = None  # collector.worlds.record.SimulatedWorld

    def run(self, out=sys.stdout, view=None) -> ValidationResult:
        """Run the validation (:func:`run_validation`) on screen ``out``; it closes the robot and camera.

        Parameters
        ----------
        out : text stream, the operator's screen
        view : collector.view.ViewOptions or None, serve the live view while the validation runs

        Returns
        -------
        ValidationResult
        """
        state = SessionState("validation", out)
        with session_view(state, view, self.camera, self.layout.path) as camera:
            return self._run(state, camera, view is not None)

    def _run(self, state, camera, viewed: bool) -> ValidationResult:
        from lasercal.collector.sessions.validate import run_validation

        out = StateStream(state)
        s = self.settings
        extra = {"collector": {"settings": s.cfg, "run": s.run}}
        if self.world is not None:
            out.write(
                f"simulated world: true robot {self.world.truth.name}, sheet at "
                f"{_pose_text(self.world.sheet)} (from {self.world.source})\n"
            )
            extra["simulated_world"] = self.world.as_dict()
        return run_validation(
            s.folder,
            self.model,
            str(s.run["model"]),
            self.layout,
            self.point,
            self.robot,
            camera,
            self.opts,
            EitherTrigger(self.trigger, state) if viewed and self.trigger is not None else self.trigger,
            self.measure,
            meta_extra=extra,
            resume=s.resume,
            confirm_moves=s.cfg["backend"] not in SIMULATED,
            state=state,
        )


def start_validation(settings: ValidateSettings, yes: bool = False) -> StartedValidation:
    """Load and cross-check the layout, point and model of a validation run; open its robot and camera.

    Parameters
    ----------
    settings : ValidateSettings (see :func:`sessions.settings.validate_settings`)
    yes : bool, the moves are confirmed in advance; otherwise typed ``yes`` on a terminal

    Returns
    -------
    StartedValidation

    Raises
    ------
    FormatError
        The layout names no such validation point, or it does not fit the model.
    SessionError
        No camera for a real robot, or a fake camera off the fake backend.
    """
    from lasercal.collector.sessions.validate import (
        ValidateOptions,
        check_layout,
        make_camera,
        validation_point,
    )

    cfg, run = settings.cfg, settings.run
    model_ref, layout_ref = settings.file("model"), settings.file("layout")
    layout = load_layout(layout_ref)
    point = validation_point(layout, run["point"])
    model = load_model(model_ref)
    check_layout(layout, model, model_ref, point)
    sheet_pose = run.get("sheet_pose")
    sheet, world = sheet_world(
        cfg, layout, model, model_ref, settings.file("sheet_from"), sheet_pose and SheetPose(*sheet_pose)
    )
    if sheet is not None:  # a printed sheet: its points where a calibration found the sheet (eq. S1)
        layout = layout.in_base(sheet)
    nominal = load_model(cfg["robot"])
    effects = world.effects if world is not None else no_effects()
    robot = make_robot(cfg, nominal, layout, truth=world and world.truth, repeat_sigma=effects.repeat_sigma)
    # where the simulated table holds the sheet, as printed and laid (collector.worlds.truesheet)
    paper = None
    if world is not None and world.sheet is not None and sheet is not None:
        paper = effects.paper(world.sheet, layout.plane_z)
    camera, measure = make_camera(
        run["camera"], cfg, robot, layout, point, layout.path, sheet, paper, effects
    )
    trigger = None
    if run["guide"] or not robot.can_move:
        trigger = AutoTrigger() if cfg["backend"] in SIMULATED else make_trigger(cfg["trigger"], robot)
    opts = ValidateOptions(
        run["n"],
        cfg["seed"],
        run["guide"],
        cfg["speed_threshold"],
        cfg["hold"],
        yes=yes,
        max_step=run["max_step"],
        photos=PhotoPolicy.of(cfg),
    )
    return StartedValidation(settings, model, layout, point, robot, camera, measure, trigger, opts, world)


@contextmanager
def session_view(state, view, camera, layout_file):
    """The live view around a session (:func:`collector.view.live_view`) when ``view`` asks for it: yields
    the camera the session photographs with (shared with the view's frames), else the camera itself."""
    if view is None:
        yield camera
        return
    from lasercal.collector.view import live_view

    with live_view(state, view, camera, layout_file) as shared:
        yield shared if shared is not None else camera


def _pose_text(pose) -> str:
    return f"x {pose.x_mm:.2f} mm, y {pose.y_mm:.2f} mm, yaw {pose.yaw_deg:.3f} deg"


def sheet_world(
    cfg: dict,
    layout: Layout,
    model: RobotModel,
    model_ref: str,
    sheet_from: str | None = None,
    pose: SheetPose | None = None,
):
    """Where a sheet layout's sheet lies for the model under test, and the fake backend's world.

    The sheet's pose is the one a calibration identified: ``sheet_from``'s (any model, the nominal
    included, can be validated with it) or the model's own. On the fake backend the simulated world is
    :func:`worlds.record.validation_world`'s: ``pose`` (the sheet's true pose), else the session the
    sheet's pose was identified from, else the layout's placement.

    Parameters
    ----------
    cfg : dict, the robot settings (``backend``, ``robot``, ``truth``, ``perturb_seed``)
    layout : Layout, as loaded (sheet or base frame)
    model : RobotModel, the model under test; model_ref : str, its file or name
    sheet_from : str or None, the model (file or name) whose sheet pose to validate with
    pose : SheetPose or None, where the simulated sheet truly lies (fake backend), in the truth's own frame

    Returns
    -------
    (SheetPose or None, SimulatedWorld or None): None, None for a base-frame layout; no world off the
    fake backend

    Raises
    ------
    FormatError
        No sheet pose to validate with; a sheet pose from a model of another robot.
    LasercalError
        ``sheet_from`` or ``pose`` on a base-frame layout, ``pose`` off the fake backend.
    """
    if layout.frame != "sheet":
        if sheet_from or pose:
            raise LasercalError(
                f"{'--sheet-from' if sheet_from else '--sheet-pose'}: the layout {layout.path} is in the "
                "base frame (its points are measured there: there is no sheet to place)"
            )
        return None, None
    if pose is not None and cfg["backend"] != "fake":
        raise LasercalError("--sheet-pose lays the simulated sheet: it needs --backend fake")
    ref = sheet_from or model_ref
    source = load_model(ref) if sheet_from else model
    if source.sheet is None:
        raise FormatError(
            ref,
            "the layout's points are on a sheet (frame: sheet) but the model has no sheet pose: validate "
            "with the sheet pose of a model solved on that sheet (--sheet-from MODEL.yaml)",
            field="sheet",
        )
    if sheet_from:
        check_same_frame(model, model_ref, source, ref)
    if cfg["backend"] != "fake":
        return source.sheet, None
    world = validation_world(
        cfg,
        load_model(cfg["robot"]),
        model_session(source, ref),
        pose,
        layout.sheet,
    )
    if world.sheet is None:
        layout.in_base()  # raises: no placement to lay the simulated sheet at (names the layout file)
    return source.sheet, world
