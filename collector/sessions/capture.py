"""The guided capture session (``lasercal capture``) as a library function.

The operator brings the laser spot onto each requested reference point in turn and
triggers; the session waits until the arm is still (every joint slower than a threshold
for a hold time), logs the joint state, appends it durably to captures.csv and shows
where the nominal model says this beam lands relative to the point -- a capture aimed at
the wrong point, or far off, is flagged at once and can be discarded -- and whether the
pose resembles an earlier one (and which joints to vary instead).

Everything the session needs comes in as objects (robot adapter, trigger, output
stream), so tests and ``--backend fake --auto`` run it without a terminal.

The loop is here (:class:`CaptureRun`); its phases beside it: the capture check and its lines
(:mod:`sessions.capturecheck`), standstill (:mod:`sessions.standstill`), the coach and the moves
(:mod:`sessions.coaching`), the photo and its spot (:mod:`sessions.spotphoto`).
"""

from __future__ import annotations

import datetime
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.collector.errors import DeviceError, RobotConnectionError
from lasercal.collector.hardware.base import RobotAdapter
from lasercal.collector.hardware.triggers import Trigger
from lasercal.collector.sessions.capturecheck import Check, check_capture, progress_lines, report_lines
from lasercal.collector.sessions.coaching import CoachSteps, aimed_layout
from lasercal.collector.sessions.motion import MAX_STEP, MotionRefused
from lasercal.collector.sessions.photos import (
    ALL_PNG,
    PhotoPolicy,
    start_estimate_line,
    written_line,
)
from lasercal.collector.sessions.spotphoto import SPOT_COLUMNS, PhotoStep
from lasercal.collector.sessions.standstill import wait_still
from lasercal.collector.sessions.state import ACTIONS, SessionState
from lasercal.collector.sessions.store import CaptureStore
from lasercal.solver.analysis.design import APART_RAD
from lasercal.solver.formats.captures import AIM_XY, EYE_XYZ
from lasercal.solver.formats.data import reference
from lasercal.solver.formats.session import Layout, check_aperture, session_layout, session_meta
from lasercal.solver.kinematics.model import RobotModel


@dataclass(frozen=True)
class CaptureOptions:
    """How a capture session behaves.

    Attributes
    ----------
    per_point : int, captures wanted at each requested point
    speed_threshold : float, the arm is still when every joint is slower than this, rad/s
    hold : float, ... for this long, s
    still_timeout : float, give up waiting for standstill after this long, s
    poll : float, interval between joint-state reads while waiting, s
    check_mm : float, flag a capture whose nominal spot is farther than this from its point, mm
    similar_rad : float, a pose closer than this (joint-space distance) to an earlier capture
        at the same point is reported as similar, rad
    auto_discard : bool, discard flagged captures without asking (the simulated operator)
    until_mm : float or None, end the session once the coach predicts at most this error at the
        validation points, mm
    move : bool, ``--guide move``: the robot moves to each suggested pose (in steps of at most
        ``max_step``) and the operator only refines the aim by hand
    yes : bool, the moves are confirmed in advance (``--yes``); otherwise typed ``yes`` on a terminal
    max_step : float, largest joint change of one commanded move, rad
    photos : PhotoPolicy, which of a camera session's photos are written, and how
    """

    per_point: int
    speed_threshold: float = 0.005
    hold: float = 0.5
    still_timeout: float = 30.0
    poll: float = (
        1 / 64
    )  # a power of two: simulated times sum exactly, so a resumed fake session repeats bit for bit
    check_mm: float = 40.0
    similar_rad: float = APART_RAD  # the coach suggests no pose this near a capture at its point
    auto_discard: bool = False
    until_mm: float | None = None
    move: bool = False
    yes: bool = False
    max_step: float = MAX_STEP
    photos: PhotoPolicy = ALL_PNG


@dataclass(frozen=True)
class CaptureResult:
    """How a session run ended: ``complete`` or stopped by the operator; captures per point on disk."""

    complete: bool
    counts: dict
    captured: int
    discarded: int


def new_session(
    folder, cfg: dict, layout: Layout, layout_path: Path, robot, nominal, rangefinder, camera=None, world=None
):
    """Create a capture session folder whose session.yaml holds everything a resume needs.

    Parameters
    ----------
    folder : the session folder to create
    cfg : dict, the capture settings (they are stored under ``collector``)
    layout : Layout; layout_path : Path, the layout file it came from
    robot : RobotAdapter, its extra columns are logged (the fake robot's truth is named as simulated)
    nominal : RobotModel, the robot the session names
    rangefinder : the rangefinder or None (then no ``laser_length_measured`` column)
    camera : the camera or None (then no :data:`SPOT_COLUMNS`)
    world : fakeworld.World or None, the simulated world's effects (fake backend)

    Returns
    -------
    CaptureStore, open for appending
    """
    columns = list(robot.extra_columns) + (["laser_length_measured"] if rangefinder is not None else [])
    # and where each photo's markers put the camera: a curled sheet's view (eq. S8)
    columns += [*SPOT_COLUMNS, *EYE_XYZ] if camera is not None else []
    columns += list(AIM_XY) if cfg.get("aim") == "anywhere" else []
    fake = cfg["backend"] == "fake"
    aperture = cfg.get("aperture_z", float(robot.truth.aperture[2]) if fake else None)
    if aperture is not None:  # refused now, not when the finished session is loaded
        check_aperture("--aperture-z", aperture, nominal)
    collector = {
        **cfg,
        "aperture_z": aperture,
        "layout": reference("layouts", layout_path, folder),  # relative to the session: it can move
        "aiming": layout.aiming,
        "extra_columns": columns,
        "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
    }
    extra = {"collector": collector}
    if fake:  # the report says what it is: simulated data
        extra["simulated"] = {
            "truth": robot.truth.name,
            "aim_noise_mm": cfg["aim_noise"],
            "seed": cfg["seed"],
        }
        if world is not None and world.effects:
            extra["simulated"]["world"] = world.as_dict()
    if cfg["backend"] == "mujoco":  # the report says simulated; the world file is named, never read for a fit
        extra["simulated"] = {"world": cfg["world"], "aim_noise_mm": cfg["aim_noise"], "seed": cfg["seed"]}
    if camera is not None and cfg.get("aim") != "anywhere":  # beside each cross: a spot on ink is biased
        from lasercal.collector.sessions.spotcam import BESIDE_MM

        extra["aim_offset"] = list(BESIDE_MM)
    return CaptureStore.create(
        folder, session_meta(cfg["robot"], layout, aperture, **extra), nominal.n, columns
    )


AIM_TOL_MM = 5.0  # the live view's circle around a hand-aimed target: a few mm is fine (a rough aim's 3 mm)


def run_capture(
    store: CaptureStore,
    robot: RobotAdapter,
    trigger: Trigger,
    nominal: RobotModel,
    opts: CaptureOptions,
    out=sys.stdout,
    rangefinder=None,
    resume_hint: str = "",
    coach=None,
    confirm_moves: bool = True,
    camera=None,
    measure=None,
    state: SessionState | None = None,
) -> CaptureResult:
    """Run (or continue) a capture session until every requested point has its captures.

    Parameters
    ----------
    store : CaptureStore, a new or reopened session; its session.yaml names the points and the order
    robot : RobotAdapter, connected by this function and closed when it returns
    trigger : Trigger
    nominal : RobotModel, the model the session names (for the on-screen check)
    opts : CaptureOptions
    out : text stream, the operator's screen (None: only ``state``'s listeners see the lines)
    rangefinder : object with ``measure() -> mm`` or None
    resume_hint : str, the command that resumes this session (said when it stops early)
    coach : lasercal.solver.analysis.design.Coach or None: before the first capture and after every
        one a status block, the next point and pose it suggests (the robot adapter is told; with
        ``opts.move`` the arm is moved there), and the stopping rule
    confirm_moves : bool, with ``opts.move``: preview and ask (:func:`collector.sessions.motion.confirm`)
        before the first move; off only for the simulated robot
    camera : a camera (``photo()``) or None: after standstill each capture is photographed, the photo kept
        (photos/, written atomically before its row) and the spot measured (:func:`spot_cells`)
    measure : callable(img, name) -> spotcam.SpotMeasure, raising VisionError when it cannot
    state : SessionState or None, what the session is doing, for the terminal and the live view (None: a
        new one that writes to ``out``)

    A Ctrl-C or a lost link stops the arm (:meth:`RobotAdapter.stop`); every capture taken is on
    disk (appended durably one by one) and ``resume_hint`` continues the session.

    Returns
    -------
    CaptureResult

    Raises
    ------
    RobotConnectionError
        The robot cannot be reached or stopped answering; the message says how to resume.
    MotionRefused
        ``opts.move`` and the moves were not confirmed: the arm did not move.
    """
    state = SessionState("capture", out) if state is None else state
    run = CaptureRun(
        store, robot, trigger, nominal, opts, state, rangefinder, resume_hint, coach, camera, measure
    )
    run.confirmed = not confirm_moves
    return run.run()


class CaptureRun(CoachSteps, PhotoStep):
    """A capture session as a state machine: each step is a method that does one thing, writes what the
    operator should know into :class:`SessionState` and returns the next step (None: the session ended).

    ``next_capture`` (the point, the coach's aim, the move there) -> ``trigger`` (the operator's command;
    hands-free: none) -> ``settle`` (standstill) -> ``record`` (photo, spot, check, the row) -> ``coached``
    (the coach's refit, the stop rule) -> ``next_capture`` ... -> ``complete`` or ``stopped``.
    Parameters as :func:`run_capture`'s.
    """

    def __init__(
        self, store, robot, trigger, nominal, opts, state, rangefinder, hint, coach, camera, measure
    ):
        self.store, self.robot, self.trigger, self.nominal, self.opts = store, robot, trigger, nominal, opts
        self.state, self.rangefinder, self.hint, self.coach = state, rangefinder, hint, coach
        self.camera, self.measure = camera, measure
        meta = store.meta
        self.meta = meta
        self.layout = session_layout(meta, store.path)
        # base frame: a sheet's points where its stated placement puts them (the check, the coach, the
        # prompt), beside the crosses where a camera session aims
        self.points = aimed_layout(self.layout, meta.get("aim_offset")).in_base().points
        self.beside = np.r_[np.asarray(meta.get("aim_offset") or (0.0, 0.0), dtype=float), 0.0]
        # --aim anywhere: the coach plans each spot in its point's cell; the operator aims there (aim_x,
        # aim_y)
        self.anywhere = meta.get("collector", {}).get("aim") == "anywhere"
        self.requested = list(meta["requested"])
        self.counts = store.counts(self.requested)
        self.captured = self.discarded = 0
        self.confirmed = False
        # --guide move with a camera: hands-free, the arm drives itself through the coach's poses and the
        # camera measures each; a pose whose spot it cannot measure is guided by hand once (then aimed)
        self.hands_free = opts.move and camera is not None
        self.settled = False  # the camera's exposure, set until a spot is read unclipped (sessions.exposure)
        self.estimated = False  # the disk the photos will take, said after the first photo
        self.by_hand = False
        self.sighted = False  # the coach plans for the camera's view, once a photo told where it stands
        self.photo_tries = 0  # photos retaken at this capture because the arm moved during one
        self.status = None  # the coach's last status
        self.name, self.aim, self.cmd = "", None, ""  # the capture under way: its point, the coach's aim
        # the page's capture or discard brought the session here: the arm stays until the terminal releases
        # the next move (the page never moves the arm)
        self.from_page = False
        self.t_shift = 0.0
        if self.camera is not None:
            self.sight_from(None)  # a resumed session plans for the camera its first photo found

    # ------------------------------------------------------------------ what the terminal and page show
    def say(self, text: str) -> None:
        self.state.say(text)

    def saved(self) -> str:
        k = len(self.store.point)
        safe = f"{k} capture{'' if k == 1 else 's'} {'is' if k == 1 else 'are'} safe in {self.store.path}"
        return safe + (f"; resume with: {self.hint}" if self.hint else "")

    def show_progress(self) -> None:
        per = self.opts.per_point
        self.state.update(progress=[{"name": k, "done": v, "want": per} for k, v in self.counts.items()])

    def todo(self) -> list[str]:
        return [nm for nm in self.requested if self.counts[nm] < self.opts.per_point]

    def run(self) -> CaptureResult:
        robot = self.robot
        step = self.start
        try:
            while step is not None:
                step = step()
        except KeyboardInterrupt:
            robot.stop()
            moved = "the arm was stopped; " if self.opts.move else ""  # a hand-guided arm is the operator's
            self.say(f"\ninterrupted: {moved}{self.saved()}\n")
            self.state.end(f"interrupted: {self.saved()}", "stopped")
            raise
        except MotionRefused as e:
            self.state.end(f"the moves were not confirmed: {self.saved()}", "stopped")
            raise MotionRefused(f"{e}; {self.saved()}") from None
        except RobotConnectionError as e:
            robot.stop()
            self.state.end(f"the robot stopped answering: {self.saved()}", "stopped")
            raise RobotConnectionError(f"{e}; {self.saved()}") from None
        except DeviceError as e:
            self.state.end(f"a device failed: {self.saved()}", "stopped")
            raise DeviceError(f"{e}; {self.saved()}") from None
        finally:
            robot.close()
        return self.result

    def start(self):
        robot, store = self.robot, self.store
        self.state.phase("setup", "connecting to the robot")
        self.show_progress()
        if store.point:  # a resumed session: a simulated arm goes back to where its last capture was
            robot.resume_at(store.q[-1], store.t[-1])
        robot.connect()
        if robot.guidance and not self.hands_free:
            self.say(f"{robot.name}: {robot.guidance}\n")
        if self.camera is not None:
            pol = self.opts.photos
            self.say(
                f"camera: each capture is photographed and its spot measured at once (captures.csv); photos "
                f"kept: {pol.words()} ({pol.choices()})\n"
            )
            left = sum(max(self.opts.per_point - k, 0) for k in self.counts.values())
            need = start_estimate_line(pol, left, len(self.requested))
            if need:
                self.say(need + "\n")
        # the session's t keeps increasing across resumes; a simulated clock that continues the session's
        # time shifts it by exactly 0, so a resumed session's t is the unbroken one's to the bit
        self.t_shift = max(store.t, default=0.0) - robot.clock.now()
        if self.coach is not None:
            self.state.phase("setup", "the coach fits the captures so far")
            # a resumed session: the coach goes through the fits (each warm-started from the one before)
            # that the uninterrupted session made, so its suggestions are the same to the last bit
            for k in range(1, len(store.q)):
                q_fit, spots = self.coach_data(k)
                if len(q_fit):
                    self.coach.update(q_fit, spots)
            self.status = self.coach_status()
        return self.next_capture

    def next_capture(self):
        """The point (and with the coach, the pose and the aim) of the next capture; the move there."""
        page = self.state.take()  # the page's stop or discard, taken before anything moves
        if page is not None:
            self.cmd = "quit" if page == "stop" else page
            self.from_page = True
            return self.command
        todo = self.todo()
        if not todo:
            return self.complete
        st, opts, lay = self.status, self.opts, self.layout
        self.name, self.aim = todo[0], None  # aim: the spot planned off the point: layout (2,), base (3,) mm
        if st is not None and st.plan.point[0] in todo:
            self.name = str(st.plan.point[0])
            if self.anywhere:
                base = st.plan.target[0]
                self.aim = (lay.sheet.from_base(base[None])[0], base)
            self.show_target()
            if opts.move and not self.by_hand:
                if not self.move_to(st.suggestion):
                    return self.command
            self.robot.suggest_pose(st.suggestion)
        self.show_target()
        self.say("\n" + "\n".join(progress_lines(self.counts, opts.per_point)) + "\n")
        self.show_progress()
        return self.trigger_step

    def show_target(self) -> None:
        """Where the spot should land, for the page: the aim (anywhere), or the point (beside it)."""
        lay, name = self.layout, self.name
        if self.aim is not None:
            xy, words = self.aim[0], f"the aim ({self.aim[0][0]:.0f}, {self.aim[0][1]:.0f}) mm"
        else:
            xy, words = (lay.points[name] + self.beside)[:2], name
        self.state.update(target={"xy": [float(v) for v in xy], "tol_mm": AIM_TOL_MM, "label": words})

    def trigger_step(self):
        """The operator's command (hands-free: none, the camera measures at once)."""
        name, opts, counts, aim = self.name, self.opts, self.counts, self.aim
        x, y, z = self.points[name]
        if self.hands_free and not self.by_hand:
            self.say(
                f"at {name}: capture {counts[name] + 1} of {opts.per_point}, hands-free  [Ctrl-C stops]\n"
            )
            self.cmd = "capture"
            return self.settle
        if aim is None:
            self.robot.prompt_point(name, self.points[name], counts[name])
            where = f"{name} ({x:.1f}, {y:.1f}, {z:.1f}) mm"
        else:
            self.robot.prompt_point(name, aim[1], counts[name], spot=aim[0])
            (sx, sy), (dx, dy) = aim[0], aim[0] - self.layout.points[name][:2]
            where = f"({sx:.0f}, {sy:.0f}) mm on the sheet ({dx:+.0f}, {dy:+.0f} mm off {name})"
        line = f"aim at {where}: capture {counts[name] + 1} of {opts.per_point}"
        self.state.phase("aiming", line, ACTIONS)
        self.say(f"{line}   [{self.trigger.hint}]\n")
        self.cmd = self.trigger.wait()
        self.from_page = getattr(self.trigger, "source", "terminal") == "page"
        return self.command

    def command(self):
        """A quit or discard from the trigger (or the page); a capture goes on to standstill."""
        if self.cmd == "quit":
            self.say(f"stopped: {self.saved()}\n")
            self.state.end(f"stopped: {self.saved()}", "stopped")
            self.result = CaptureResult(False, self.counts, self.captured, self.discarded)
            return None
        if self.cmd == "discard":
            gone = self.store.discard_last()
            if gone is None:
                self.say("nothing to discard\n")
            else:
                if gone in self.counts:  # a row at a point no longer requested counts nowhere
                    self.counts[gone] -= 1
                self.discarded += 1
                self.say(f"discarded the last capture at {gone}\n")
                self.show_progress()
            return self.next_capture
        return self.settle

    def settle(self):
        opts = self.opts
        self.state.phase("settling", "hold still: the arm must be still before the photo", ACTIONS[2:])
        shown = [0.0]

        def countdown(peak: float, held: float) -> None:
            now = time.monotonic()
            if now - shown[0] > 0.1:  # at most ten updates a second: a simulated clock polls far faster
                shown[0] = now
                left = max(opts.hold - held, 0.0)
                self.state.update(
                    standstill={
                        "left_s": left,
                        "max_dq": peak,
                        "threshold": opts.speed_threshold,
                        "hold_s": opts.hold,
                    }
                )

        self.still, peak = wait_still(
            self.robot, opts.speed_threshold, opts.hold, opts.still_timeout, opts.poll, countdown
        )
        self.state.update(standstill=None)
        if self.state.stop_asked():  # the page's stop while the arm settled: nothing photographed
            self.cmd = "quit"
            return self.command
        if self.still is None:
            msg = (
                f"the arm did not come to rest within {opts.still_timeout:g} s (max |dq| {peak:.4f} "
                "rad/s): not captured"
            )
            self.say(msg + "\n")
            self.state.problem(msg)
            return self.next_capture
        self.peak = peak
        return self.record

    def record(self):
        """Photograph and measure the capture, check it with the nominal model, append its row."""
        store, state, name, aim, opts = self.store, self.still, self.name, self.aim, self.opts
        camera, counts, lay = self.camera, self.counts, self.layout
        self.state.update(problem=None)  # what went wrong before: this capture's photo supersedes it
        length = self.rangefinder.measure() if self.rangefinder is not None else None
        earlier = np.array([q for p, q in zip(store.point, store.q) if p == name]).reshape(-1, len(state.q))
        check = check_capture(self.nominal, self.points, name, state.q, earlier, opts, aim)
        t = state.t + self.t_shift
        extra = dict(state.extra)
        if length is not None:
            extra["laser_length_measured"] = length
        seen, got = "", None
        if camera is not None:
            step, got, seen = self.photograph(t)
            if step is not None:
                return step
            extra.update(got.cells)
        self.by_hand = False
        spot = lay.points[name] + self.beside  # where it was aimed, layout frame (a sheet's: z 0)
        if aim is not None:
            extra.update(aim_x=aim[0][0], aim_y=aim[0][1])
            spot = np.r_[aim[0], spot[2]]
        aimed_xy = spot[:2].copy()
        if "camera_x" in extra:
            spot = np.r_[extra["camera_x"], extra["camera_y"], spot[2]]
        if lay.frame == "sheet":
            spot = np.r_[spot[:2], lay.plane_z]  # as load_session's target: z the plane's height
        row = {"point": name, "t": t, "q": state.q, "dq": state.dq, "tau": state.tau, "target": spot}
        store.append({**row, **extra})
        counts[name] += 1
        self.captured += 1
        self.say("\n".join(report_lines(check, counts[name], t, self.peak, length)) + "\n" + seen)
        self.show_last(check, got, aimed_xy)
        self.show_progress()
        if check.flag and opts.auto_discard:
            store.discard_last()
            counts[name] -= 1
            self.discarded += 1
            self.say("discarded it (the simulated operator heeds the warning)\n")
            self.show_progress()
            return self.next_capture
        return self.coached

    def show_last(self, check: Check, got, aimed_xy: np.ndarray) -> None:
        """The last capture, for the page: its measured spot and how far it lies from where it was aimed."""
        last = {"point": self.name, "number": self.counts[self.name], "measured": False, "flag": check.flag}
        if np.all(np.isfinite(check.offset)):
            last["nominal_mm"] = float(np.hypot(*check.offset))
        if got is not None and got.measured:
            xy = np.array([got.cells["camera_x"], got.cells["camera_y"]], dtype=float)
            last.update(
                measured=True,
                spot=[float(v) for v in xy],
                sigma=[float(got.cells["camera_sx"]), float(got.cells["camera_sy"])],
                from_aim_mm=float(np.hypot(*(xy - aimed_xy))),
            )
        phase = "captured" if got is None or got.measured else "problem"
        self.state.update(last=last)
        self.state.phase(phase, f"captured {self.name} #{self.counts[self.name]}", ACTIONS[1:])

    def coached(self):
        if self.coach is None:
            return self.next_capture
        self.status = st = self.coach_status()
        until = self.opts.until_mm
        if until is not None and st.predicted <= until:
            self.say(
                f"predicted error at {st.region} {st.predicted:.2f} mm <= --until {until:g} mm: session "
                "complete\n"
            )
            return self.finish
        return self.next_capture

    def complete(self):
        self.say("\n" + "\n".join(progress_lines(self.counts, self.opts.per_point)) + "\n")
        return self.finish

    def finish(self):
        total = sum(self.counts.values())
        self.say(f"session complete: {total} captures in {self.store.path}\n")
        if self.camera is not None:
            self.say(written_line(self.store.folder) + "\n")
        self.state.end(f"session complete: {total} captures in {self.store.path}")
        self.result = CaptureResult(True, self.counts, self.captured, self.discarded)
        return None
