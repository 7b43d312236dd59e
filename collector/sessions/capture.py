"""The guided capture session (``lasercal capture``) as a library function.

The operator brings the laser spot onto each requested reference point in turn and
triggers; the session waits until the arm is still (every joint slower than a threshold
for a hold time), logs the joint state, appends it durably to captures.csv and shows
where the nominal model says this beam lands relative to the point -- a capture aimed at
the wrong point, or far off, is flagged at once and can be discarded -- and whether the
pose resembles an earlier one (and which joints to vary instead).

Everything the session needs comes in as objects (robot adapter, trigger, output
stream), so tests and ``--backend fake --auto`` run it without a terminal.
"""

from __future__ import annotations

import datetime
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from lasercal.collector.errors import DeviceError, RobotConnectionError
from lasercal.collector.hardware.base import FakeClock, JointState, RobotAdapter
from lasercal.collector.hardware.triggers import Trigger
from lasercal.collector.report.text import identifiable_text
from lasercal.collector.sessions.anywhere import CAMERA_NOISE_MM
from lasercal.collector.sessions.exposure import readable_by, settle_exposure
from lasercal.collector.sessions.motion import MAX_STEP, MotionRefused, confirm, plan_moves, preview
from lasercal.collector.sessions.photos import (
    ALL_PNG,
    PhotoPolicy,
    estimate_line,
    start_estimate_line,
    written_line,
)
from lasercal.collector.sessions.state import ACTIONS, SessionState
from lasercal.collector.sessions.store import CaptureStore
from lasercal.solver.analysis.design import APART_RAD
from lasercal.solver.formats.captures import AIM_XY
from lasercal.solver.formats.data import reference
from lasercal.solver.formats.session import Layout, check_aperture, session_layout, session_meta
from lasercal.solver.identify.spot import predict_spots
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
class Check:
    """What the nominal model says about one capture.

    Attributes
    ----------
    point : str, the point the operator was asked for
    offset : (2,) array, nominal spot minus the point, mm (NaN when the beam points away from the plane)
    nearest : str, the reference point nearest to the nominal spot
    flag : str, why the capture looks wrong ('' when it looks right)
    similar_to : int or None, 1-based number (at this point) of the most similar earlier capture
    distance : float, its joint-space distance, rad
    vary : tuple of int, 1-based joints whose spread over this point's captures is smallest
    aim : (2,) array or None, the spot the coach planned off the point (layout frame, mm): ``offset`` is
        then measured from it, not from the point
    """

    point: str
    offset: np.ndarray
    nearest: str
    flag: str
    similar_to: int | None
    distance: float
    vary: tuple
    aim: np.ndarray | None = None

    @property
    def target(self) -> str:
        """What ``offset`` is measured from, in words: the point, or the aim the coach planned."""
        if self.aim is None:
            return self.point
        return f"the aim ({self.aim[0]:.0f}, {self.aim[1]:.0f}) mm on the sheet"


@dataclass(frozen=True)
class CaptureResult:
    """How a session run ended: ``complete`` or stopped by the operator; captures per point on disk."""

    complete: bool
    counts: dict
    captured: int
    discarded: int


def check_capture(
    nominal: RobotModel,
    points: dict,
    name: str,
    q: np.ndarray,
    earlier: np.ndarray,
    opts: CaptureOptions,
    aim: tuple | None = None,
) -> Check:
    """The nominal-model check and the pose-diversity hint of a new capture.

    Parameters
    ----------
    nominal : RobotModel
    points : dict name -> (3,) array, mm
    name : str, the point the operator was asked for
    q : (n,) array, the captured configuration, rad
    earlier : (k, n) array, earlier captures at this point, rad
    opts : CaptureOptions
    aim : ((2,) array, (3,) array) or None, the spot the coach planned in the point's cell (layout frame,
        base frame; mm): the beam is checked against it (``--aim anywhere``), not against the point
    """
    p = points[name] if aim is None else aim[1]
    spot, length = predict_spots(nominal, q[None], p[2])
    mark = None if aim is None else np.asarray(aim[0], dtype=float)
    if length[0] <= 0:
        return Check(
            name,
            np.full(2, np.nan),
            "",
            "the nominal beam points away from the table",
            None,
            np.nan,
            (),
            mark,
        )
    offset = spot[0, :2] - p[:2]
    others = {**points, name: p}
    nearest = min(others, key=lambda k: np.linalg.norm(spot[0, :2] - others[k][:2]))
    flag = ""
    where = name if aim is None else "the aim"
    # within check_mm of its point the spot is the nominal model's error, even nearer another point (crosses
    # on a printed sheet lie 40-50 mm apart); beyond it, the nearer point names the likely mistake
    if np.linalg.norm(offset) > opts.check_mm and nearest != name:
        flag = f"the beam lands nearest to {nearest}, not {where}: aimed at the wrong point?"
    elif np.linalg.norm(offset) > opts.check_mm:
        flag = (
            f"{np.linalg.norm(offset):.0f} mm from {where} by the nominal model (more than "
            f"{opts.check_mm:g} mm): aimed at the wrong place, or the arm moved?"
        )
    similar_to, distance, vary = None, np.nan, ()
    if len(earlier):
        d = np.linalg.norm(earlier - q, axis=1)
        k = int(np.argmin(d))
        distance = float(d[k])
        if distance < opts.similar_rad:
            similar_to = k + 1
            spread = np.vstack([earlier, q]).std(axis=0) / np.ptp(nominal.limits, axis=1)
            vary = tuple(int(j) + 1 for j in np.argsort(spread)[:2])
    return Check(name, offset, nearest, flag, similar_to, distance, vary, mark)


# mm: the most the spot may move (under the nominal model) from the standstill read the row logs to a read
# after its photo: a tenth of a measured spot's noise (0.02-0.05 mm). An arm that creeps more (a real-time
# arm still settling: franky-sim's moved it 0.04 mm under load) is photographed again after a new standstill.
PHOTO_MOVED_MM = 0.005
PHOTO_TRIES = 3


def moved_during_photo(robot: RobotAdapter, still: JointState, model: RobotModel, plane_z: float) -> float:
    """How far (mm) the spot moved on the plane ``plane_z`` under ``model`` from the standstill read ``still``
    to a read after the photo; 0 for an arm on a simulated clock, which cannot move while nothing sleeps
    (and whose reads draw its noise)."""
    if isinstance(robot.clock, FakeClock):
        return 0.0
    spots = predict_spots(model, np.array([still.q, robot.read().q]), plane_z)[0]
    return float(np.linalg.norm(spots[1] - spots[0]))


def wait_still(
    robot: RobotAdapter, threshold: float, hold: float, timeout: float, poll: float, tick=None
) -> tuple[JointState | None, float]:
    """Poll the arm until every joint has been slower than ``threshold`` (rad/s) for ``hold`` s.

    Parameters
    ----------
    robot : RobotAdapter
    threshold : float, rad/s
    hold : float, s
    timeout : float, give up after this long, s
    poll : float, interval between reads, s
    tick : callable(peak, held) or None, told after every read: the largest joint speed (rad/s) and how long
        the arm has been still (s), for a countdown

    Returns
    -------
    state : the reading that completed the hold, or None after ``still_timeout``
    peak : float, largest joint speed of the last reading, rad/s
    """
    clock = robot.clock
    start = clock.now()
    since = None
    while True:
        s = robot.read()
        peak = float(np.abs(s.dq).max())
        if peak < threshold:
            since = s.t if since is None else since
            if s.t - since >= hold:
                return s, peak
        else:
            since = None
        if tick is not None:
            tick(peak, 0.0 if since is None else s.t - since)
        if s.t - start > timeout:
            return None, peak
        clock.sleep(poll)


def progress_lines(counts: dict, per_point: int, width: int = 20) -> list[str]:
    """One progress bar per point: done and left."""
    out = []
    for nm, k in counts.items():
        full = round(width * min(k, per_point) / per_point)
        out.append(
            f"  {nm:<6} [{'#' * full}{'-' * (width - full)}] {k:3d}/{per_point}  {max(per_point - k, 0):3d} "
            "left"
        )
    return out


def _report(check: Check, number: int, t: float, peak: float, length: float | None) -> list[str]:
    lines = [
        f"captured {check.point} #{number} at t = {t:.1f} s (still, max |dq| {peak:.4f} rad/s)"
        + (f", laser length {length:.1f} mm" if length is not None else "")
    ]
    if np.all(np.isfinite(check.offset)):
        dx, dy = check.offset
        lines.append(
            f"  nominal model: the beam lands {np.hypot(dx, dy):.1f} mm from {check.target} (dx {dx:+.1f}, "
            f"dy {dy:+.1f} mm)"
        )
    if check.flag:
        lines.append(f"  ! {check.flag} -- discard it?")
    if check.similar_to is not None:
        joints = " and ".join(str(j) for j in check.vary)
        lines.append(
            f"  ~ similar to capture #{check.similar_to} at {check.point} (joint distance "
            f"{check.distance:.2f} rad): "
            f"vary joints {joints} for the next ones"
        )
    return lines


JOINT_WORDS = {  # what moving each joint of a Panda-like 7-joint arm looks like to the operator
    1: "turn the base",
    2: "lean the shoulder",
    3: "twist the upper arm",
    4: "bend the elbow",
    5: "twist the forearm",
    6: "bend the wrist",
    7: "turn the flange",
}


def coach_lines(st, counts: dict, current: np.ndarray, stop_gain: float, done: bool = False) -> list[str]:
    """The coach's status block after a capture (or before the first: the prior's verdict).

    Parameters
    ----------
    st : lasercal.solver.analysis.design.Status
    counts : dict point -> captures
    current : (n,) array, the arm's configuration (the last capture's), rad
    stop_gain : float, the stopping rule's threshold (fraction)
    done : bool, every requested capture is taken: no next pose is suggested
    """
    per = ", ".join(f"{k} {v}" for k, v in counts.items())
    # with no captures the prediction is the prior's, which does not depend on the aiming noise
    f = 3 if st.predicted < 0.1 else 2  # a camera session's hundredths of a mm keep two figures
    spread = f"± {st.uncertainty:.{f}f} mm" if st.captures else "mm (prior)"
    lines = [
        f"  coach: captures {per}; {identifiable_text(st.rank, st.n_params, st.n_identifiable)}",
        f"  predicted error at {st.region}: {st.predicted:.{f}f} {spread}",
    ]
    wk = st.weakest
    weak = f"  weakest: {', '.join(wk.params)} ({wk.share * 100:.0f} % of the predicted error)"
    if wk.joint is not None:
        lo, hi = np.degrees(wk.captured)
        # the words describe a Panda-like 7-joint arm; any other arm is told the joint's number
        words = JOINT_WORDS[wk.joint] if len(current) == 7 else f"move joint {wk.joint}"
        span = "barely varied" if hi - lo < 20 else "varied"
        weak += (
            f"; joint {wk.joint} {span} ({lo:.0f}..{hi:.0f} deg), the informative poses have it near "
            f"{np.degrees(wk.wanted):.0f} deg: {words} that way"
        )
    lines.append(weak)
    if done:
        lines.append("  next: none, every requested capture is taken")
    else:
        dq = np.degrees(st.suggestion - current)
        order = np.argsort(-np.abs(dq))
        moves = ", ".join(f"joint {j + 1} {dq[j]:+.0f}" for j in order if abs(dq[j]) >= 1.0) or "none"
        lines.append(f"  next: {st.plan.point[0]}, from this pose change (deg): {moves}")
    if st.stop:
        lines.append(
            f"  expected error at {st.region} {st.predicted:.2f} ± {st.uncertainty:.2f} mm; "
            f"{len(st.plan.expected)} more captures would improve it by < {stop_gain * 100:.0f} %: "
            "you can stop"
        )
    return lines


# a camera session's columns (docs/formats.md)
SPOT_COLUMNS = ("photo", "camera_x", "camera_y", "camera_sx", "camera_sy", "camera_note")


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
    columns += list(SPOT_COLUMNS) if camera is not None else []
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


@dataclass(frozen=True)
class Seen:
    """What the camera made of a capture (:func:`spot_cells`).

    Attributes
    ----------
    cells : dict, the row's :data:`SPOT_COLUMNS` (``photo`` empty when the photo was not kept)
    said : str, the line(s) said at once; without a final newline when the spot was not measured (the
        caller says what becomes of the capture)
    nbytes : int, the photo's size as encoded for its file, bytes (0 with ``--photos none``)
    img : (h, w, 3) uint8 array, the photo
    """

    cells: dict
    said: str
    nbytes: int
    img: np.ndarray

    @property
    def measured(self) -> bool:
        return "camera_x" in self.cells


def read_unclipped(seen: Seen) -> bool:
    """The photo's spot was measured, and not so clipped that the measurement advises a lower exposure
    (:func:`vision.exposure.exposure_advice`: clipped over more than ``CLIPPED_MAX`` px)."""
    return seen.measured and "spot clipped over" not in seen.cells.get("camera_note", "")


def spot_cells(
    folder: Path,
    camera,
    measure,
    t: float,
    point: np.ndarray,
    meta: dict,
    img=None,
    policy: PhotoPolicy = ALL_PNG,
    first: bool = True,
) -> Seen:
    """Photograph a capture, measure its spot and keep the photo as ``policy`` says: the row's
    :data:`SPOT_COLUMNS` and the line(s) said at once.

    A spot that cannot be measured (hidden by the arm, outside the view, unreadable, two candidates)
    leaves ``camera_x``..``camera_sy`` empty and its reason in ``camera_note``. The spot is measured from
    the photo in memory: a photo not kept (:class:`~collector.sessions.photos.PhotoPolicy`) loses nothing
    of the measurement.

    Parameters
    ----------
    folder : Path, the session folder (photos/ is made in it)
    camera, measure : see :func:`run_capture`
    t : float, the capture's session time, s (names the photo: unique across resumes)
    point : (3,) array, where the spot was aimed, base frame at the placement (the message's distance), mm
    meta : dict, session.yaml (a sheet's placement maps the measured spot to the base frame)
    img : (h, w, 3) array or None, the photo if already taken (None: taken here)
    policy : PhotoPolicy, which photos are written and how
    first : bool, the first capture at its point (``--photos first`` keeps it)
    """
    from lasercal.collector.sessions.store import write_atomic_bytes
    from lasercal.vision.errors import VisionError

    img = camera.photo() if img is None else img
    name = f"photos/capture_{int(round(t * 1000)):09d}.{policy.fmt}"
    try:
        m = measure(img, name)
    except VisionError as e:
        why = (str(e).split(": ", 1)[-1] if str(e).startswith(name) else str(e)).replace("\n", " ")
        cells, said = (
            {"photo": name, "camera_note": why},
            f"  ! camera: the spot could not be measured ({why})",
        )
    else:
        cells = {"photo": name, "camera_x": m.xy[0], "camera_y": m.xy[1], "camera_sx": m.sigma[0]}
        cells.update(camera_sy=m.sigma[1], camera_note=m.note.replace("\n", " "))
        layout = session_layout(meta, folder)
        said = f"  camera: spot at ({m.xy[0]:.3f}, {m.xy[1]:.3f}) mm +- ({m.sigma[0]:.3f}, {m.sigma[1]:.3f})"
        if (
            layout.frame != "sheet" or layout.sheet is not None
        ):  # where the placement puts it: the cross's frame
            where = layout.sheet.to_base(m.xy[None], layout.plane_z)[0] if layout.frame == "sheet" else m.xy
            said += f", {np.hypot(*(np.asarray(where)[:2] - point[:2])):.1f} mm from the aim"
        said += "\n"
    data = b"" if policy.keep == "none" else policy.encode(img, name)
    if policy.kept(first, "camera_x" in cells):
        (folder / "photos").mkdir(exist_ok=True)
        write_atomic_bytes(folder / name, data)  # before the row: a row never names a missing photo
    else:
        cells["photo"] = ""
    return Seen(cells, said, len(data), img)


def aimed_layout(layout: Layout, offset) -> Layout:
    """The layout with its points where the operator aims: ``offset`` (dx, dy) mm beside each (a camera
    session's ``aim_offset``, in the layout's frame), or the layout itself without one."""
    if offset is None:
        return layout
    shift = np.r_[np.asarray(offset, dtype=float), 0.0]
    return replace(layout, points={k: v + shift for k, v in layout.points.items()})


def session_coach(
    store: CaptureStore, nominal: RobotModel, layout: Layout, cfg: dict, sheet=None, anywhere=None
):
    """The capture coach of a session: the nominal model with the session's measured aperture height;
    ``layout`` in the base frame, ``sheet``: the SheetPose (placement) of a sheet its points lie on, whose
    pose, print and tilt ``solve`` identifies, ``anywhere``: name -> (k, 3) spots in each point's cell,
    base frame, mm (:mod:`sessions.anywhere`)."""
    from lasercal.solver.analysis.design import Coach
    from lasercal.solver.formats.tolerances import robot_tolerances

    aperture_z = store.meta.get("laser", {}).get("aperture_z")
    model = (
        nominal if aperture_z is None else nominal.replace(aperture=np.r_[nominal.aperture[:2], aperture_z])
    )
    # a camera session's captures are measured: the camera's noise and what it does not see (the noise
    # camera sessions find, docs/sessions.md), not the aiming noise
    noise = CAMERA_NOISE_MM if cfg.get("camera") else cfg["aim_noise"]
    tol = robot_tolerances(nominal).with_noise("laser", noise)
    return Coach(model, layout, cfg["seed"], tol, sheet=sheet is not None, anywhere=anywhere, pose=sheet)


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


class CaptureRun:
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
        self.photo_tries = 0  # photos retaken at this capture because the arm moved during one
        self.status = None  # the coach's last status
        self.name, self.aim, self.cmd = "", None, ""  # the capture under way: its point, the coach's aim
        # the page's capture or discard brought the session here: the arm stays until the terminal releases
        # the next move (the page never moves the arm)
        self.from_page = False
        self.t_shift = 0.0

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

    # ------------------------------------------------------------------ the coach
    def spots_in_base(self, targets) -> np.ndarray:
        """Where the captures' spots were (layout frame, a measured spot or the aim), in the base frame at
        the sheet's placement: the coach fits the camera's measurements, as solve will."""
        t = np.array(targets, dtype=float).reshape(-1, 3)
        lay = self.layout
        return lay.sheet.to_base(t[:, :2], lay.plane_z) if lay.frame == "sheet" else t

    def coach_data(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The first k captures the coach fits, (k, n) rad and (k, 3) mm base frame. In a camera session a
        capture the camera could not measure enters as spent: its spot where the coach's fit predicts it
        (an aimed spot's residual, at the aiming noise, would be taken for the camera's noise; left out,
        the coach would ask for the same hidden pose again)."""
        store = self.store
        q = np.asarray(store.q[:k], dtype=float).reshape(-1, self.nominal.n)
        spots = self.spots_in_base(store.target[:k])
        spent = ~np.array(store.measured[:k], bool)
        if self.camera is not None and spent.any():
            spots[spent] = predict_spots(self.coach.post.model, q[spent], spots[spent, 2])[0]
        return q, spots

    def coach_status(self):
        """Refit the coach on every capture so far and say its status block (the prior's with none)."""
        store, coach = self.store, self.coach
        todo = self.todo()
        q_all = np.asarray(store.q, dtype=float).reshape(len(store.point), self.nominal.n)
        q_fit, spots = self.coach_data(len(q_all))
        if len(q_fit):
            coach.update(q_fit, spots)
        aimed = np.array([self.points[p] for p in store.point]).reshape(-1, 3)  # no suggestion where taken
        st = coach.status(q_fit, allowed=todo or None, target=aimed)
        current = q_all[-1] if len(q_all) else self.robot.read().q
        lines = coach_lines(st, self.counts, current, coach.stop_gain, done=not todo)
        self.say("\n".join(lines) + "\n")
        self.state.update(
            coach={
                "predicted_mm": float(st.predicted),
                "uncertainty_mm": float(st.uncertainty),
                "region": str(st.region),
                "stop": bool(st.stop),
                "captures": int(st.captures),
                "lines": [ln.strip() for ln in lines],
            }
        )
        return st

    # ------------------------------------------------------------------ the steps
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

    def released(self) -> bool:
        """After the page's capture or discard the arm stays where it is: the move to the next pose waits
        for the terminal (its trigger: Enter, a pedal, the simulated operator), which releases this one
        move; the terminal's quit, or the page's stop, ends the session, the terminal's discard is taken
        (and releases the move after it). True when released."""
        wait = getattr(self.trigger, "wait_terminal", None)
        if wait is None:  # no page: every command is the terminal's
            self.from_page = False
            return True
        line = (
            "the arm stays here: the move to the next pose waits for the terminal (the page cannot move it)"
        )
        self.state.phase("confirm", line, ("stop",))
        self.say(f"  {line}; the terminal's capture releases it   [{self.trigger.hint}]\n")
        cmd = wait()
        self.from_page = False
        if cmd == "capture":
            self.say("  released at the terminal: moving\n")
            return True
        self.cmd = cmd  # quit, or discard: taken by ``command`` (a discard's move is the terminal's)
        return False

    def move_to(self, q: np.ndarray) -> bool:
        """``--guide move``: to q in steps of at most ``max_step``; confirmed before the first move, and
        after a page's capture or discard released at the terminal (:meth:`released`). False when the
        session does not move now: stopped (the page's stop between two steps: the arm stays where it is),
        or a discard asked instead."""
        robot, opts = self.robot, self.opts
        if self.state.stop_asked():
            self.cmd = "quit"
            return False
        if self.from_page and not self.released():
            return False
        plan = plan_moves(robot.read().q, q[None], self.nominal, opts.max_step)
        self.say(preview(plan))
        if not self.confirmed:
            self.state.phase("confirm", "confirm the moves in the terminal: the page cannot", ("stop",))
            confirm(plan, opts.yes, out=StateStream(self.state))
            self.confirmed = True
        for k, step in enumerate(plan.steps):
            self.state.phase(
                "moving", f"moving to the suggested pose: step {k + 1} of {len(plan.steps)}", ACTIONS[2:]
            )
            page = self.state.take()
            if page is not None:
                self.cmd = "quit" if page == "stop" else page
                return False
            robot.move_to(step)
        self.say(
            "  at the suggested pose: the camera measures where the beam lands\n"
            if self.hands_free and not self.by_hand
            else "  at the suggested pose: refine the aim by hand, then trigger\n"
        )
        return True

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
            self.state.phase("photo", "photographing the spot")
            # the exposure is set with the laser on a point, and again at each capture until a photo's spot
            # was read unclipped: a first spot off the markers' area, or one that clips later, does not fix it
            first = None if self.settled else settle_exposure(camera, readable_by(self.measure))
            aimed_at = self.points[name] if aim is None else aim[1]
            got = spot_cells(
                store.folder,
                camera,
                self.measure,
                t,
                aimed_at,
                self.meta,
                first,
                opts.photos,
                counts[name] == 0,
            )
            self.settled = self.settled or read_unclipped(got)
            if first is not None and not self.estimated:  # the run's first photo: what the photos will take
                self.estimated = True
                left = sum(max(opts.per_point - k, 0) for k in counts.values())
                self.say(estimate_line(opts.photos, got.nbytes, left, len(self.requested)) + "\n")
            moved = moved_during_photo(self.robot, state, self.nominal, lay.plane_z)
            if moved > PHOTO_MOVED_MM and self.photo_tries < PHOTO_TRIES:
                self.photo_tries += 1
                self.say(
                    f"  the arm moved the spot {moved:.3f} mm while photographed (more than "
                    f"{PHOTO_MOVED_MM:g}): photographing again once it is still\n"
                )
                return self.settle
            self.photo_tries = 0
            extra.update(got.cells)
            seen = got.said
            if got.measured:
                pass
            elif self.hands_free and not self.by_hand:  # no aim and no measurement: no data
                why = got.cells["camera_note"]
                self.say(
                    f"{seen}: not kept; this pose is guided by hand once: aim beside the cross, trigger\n"
                )
                self.state.problem(
                    f"the camera could not measure the spot ({why}): guided by hand once", got.img
                )
                self.by_hand = True
                return self.next_capture
            else:
                seen += (
                    ": kept as an aimed capture, fitted to where it was aimed with the aiming noise "
                    "(d Enter discards it, to retake it)\n"
                )
                self.state.problem(
                    f"the camera could not measure the spot ({got.cells['camera_note']}): kept as an aimed "
                    "capture",
                    got.img,
                )
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
        self.say("\n".join(_report(check, counts[name], t, self.peak, length)) + "\n" + seen)
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


class StateStream:
    """A text stream that says through a SessionState (what :func:`motion.confirm` prints)."""

    def __init__(self, state: SessionState):
        self.state = state

    def write(self, text: str) -> None:
        self.state.say(text)

    def flush(self) -> None:
        """Nothing buffered."""
