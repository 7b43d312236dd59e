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
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from lasercal.collector.errors import DeviceError, RobotConnectionError
from lasercal.collector.hardware.base import JointState, RobotAdapter
from lasercal.collector.hardware.triggers import Trigger
from lasercal.collector.report.text import identifiable_text
from lasercal.collector.sessions.anywhere import CAMERA_NOISE_MM
from lasercal.collector.sessions.exposure import readable_by, settle_exposure
from lasercal.collector.sessions.motion import MAX_STEP, MotionRefused, confirm, plan_moves, preview
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
    """

    point: str
    offset: np.ndarray
    nearest: str
    flag: str
    similar_to: int | None
    distance: float
    vary: tuple


@dataclass(frozen=True)
class CaptureResult:
    """How a session run ended: ``complete`` or stopped by the operator; captures per point on disk."""

    complete: bool
    counts: dict
    captured: int
    discarded: int


def check_capture(
    nominal: RobotModel, points: dict, name: str, q: np.ndarray, earlier: np.ndarray, opts: CaptureOptions
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
    """
    p = points[name]
    spot, length = predict_spots(nominal, q[None], p[2])
    if length[0] <= 0:
        return Check(
            name, np.full(2, np.nan), "", "the nominal beam points away from the table", None, np.nan, ()
        )
    offset = spot[0, :2] - p[:2]
    names = list(points)
    nearest = names[int(np.argmin([np.linalg.norm(spot[0, :2] - points[k][:2]) for k in names]))]
    flag = ""
    # within check_mm of its point the spot is the nominal model's error, even nearer another point (crosses
    # on a printed sheet lie 40-50 mm apart); beyond it, the nearer point names the likely mistake
    if np.linalg.norm(offset) > opts.check_mm and nearest != name:
        flag = f"the beam lands nearest to {nearest}, not {name}: aimed at the wrong point?"
    elif np.linalg.norm(offset) > opts.check_mm:
        flag = (
            f"{np.linalg.norm(offset):.0f} mm from {name} by the nominal model (more than {opts.check_mm:g} "
            "mm): "
            "aimed at the wrong place, or the arm moved?"
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
    return Check(name, offset, nearest, flag, similar_to, distance, vary)


def wait_still(
    robot: RobotAdapter, threshold: float, hold: float, timeout: float, poll: float
) -> tuple[JointState | None, float]:
    """Poll the arm until every joint has been slower than ``threshold`` (rad/s) for ``hold`` s.

    Parameters
    ----------
    robot : RobotAdapter
    threshold : float, rad/s
    hold : float, s
    timeout : float, give up after this long, s
    poll : float, interval between reads, s

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
            f"  nominal model: the beam lands {np.hypot(dx, dy):.1f} mm from {check.point} (dx {dx:+.1f}, dy "
            f"{dy:+.1f} mm)"
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


def spot_cells(
    folder: Path, camera, measure, t: float, point: np.ndarray, meta: dict, img=None
) -> tuple[dict, str]:
    """Photograph a capture, keep the photo and measure its spot: the row's :data:`SPOT_COLUMNS` and the
    line(s) said at once.

    A spot that cannot be measured (hidden by the arm, outside the view, unreadable, two candidates)
    leaves ``camera_x``..``camera_sy`` empty and its reason in ``camera_note``; the line said then has no
    newline: the caller says what becomes of the capture.

    Parameters
    ----------
    folder : Path, the session folder (photos/ is made in it)
    camera, measure : see :func:`run_capture`
    t : float, the capture's session time, s (names the photo: unique across resumes)
    point : (3,) array, where the spot was aimed, base frame at the placement (the message's distance), mm
    meta : dict, session.yaml (a sheet's placement maps the measured spot to the base frame)
    img : (h, w, 3) array or None, the photo if already taken (None: taken here)
    """
    import cv2

    from lasercal.collector.sessions.store import write_atomic_bytes
    from lasercal.vision.errors import VisionError

    img = camera.photo() if img is None else img
    name = f"photos/capture_{int(round(t * 1000)):09d}.png"
    ok, png = cv2.imencode(".png", img)
    if not ok:
        raise DeviceError(f"cannot encode photo {name}")
    (folder / "photos").mkdir(exist_ok=True)
    write_atomic_bytes(folder / name, png.tobytes())  # before the row: a row never names a missing photo
    try:
        m = measure(img, name)
    except VisionError as e:
        why = (str(e).split(": ", 1)[-1] if str(e).startswith(name) else str(e)).replace("\n", " ")
        return {"photo": name, "camera_note": why}, f"  ! camera: the spot could not be measured ({why})"
    cells = {"photo": name, "camera_x": m.xy[0], "camera_y": m.xy[1], "camera_sx": m.sigma[0]}
    cells.update(camera_sy=m.sigma[1], camera_note=m.note.replace("\n", " "))
    layout = session_layout(meta, folder)
    said = f"  camera: spot at ({m.xy[0]:.3f}, {m.xy[1]:.3f}) mm +- ({m.sigma[0]:.3f}, {m.sigma[1]:.3f})"
    if layout.frame != "sheet" or layout.sheet is not None:  # where the placement puts it: the cross's frame
        where = layout.sheet.to_base(m.xy[None], layout.plane_z)[0] if layout.frame == "sheet" else m.xy
        said += f", {np.hypot(*(np.asarray(where)[:2] - point[:2])):.1f} mm from the aim"
    return cells, said + "\n"


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
) -> CaptureResult:
    """Run (or continue) a capture session until every requested point has its captures.

    Parameters
    ----------
    store : CaptureStore, a new or reopened session; its session.yaml names the points and the order
    robot : RobotAdapter, connected by this function and closed when it returns
    trigger : Trigger
    nominal : RobotModel, the model the session names (for the on-screen check)
    opts : CaptureOptions
    out : text stream, the operator's screen
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
    meta = store.meta
    # base frame: a sheet's points where its stated placement puts them (the check, the coach, the prompt),
    # beside the crosses where a camera session aims
    points = aimed_layout(session_layout(meta, store.path), meta.get("aim_offset")).in_base().points
    requested = list(meta["requested"])
    counts = store.counts(requested)
    w = out.write
    captured = discarded = 0
    confirmed = [not confirm_moves]

    def saved() -> str:
        k = len(store.point)
        safe = f"{k} capture{'' if k == 1 else 's'} {'is' if k == 1 else 'are'} safe in {store.path}"
        return safe + (f"; resume with: {resume_hint}" if resume_hint else "")

    layout = session_layout(meta, store.path)
    beside = np.r_[np.asarray(meta.get("aim_offset") or (0.0, 0.0), dtype=float), 0.0]
    # --aim anywhere: the coach plans each spot in its point's cell; the operator aims there (aim_x, aim_y)
    anywhere = meta.get("collector", {}).get("aim") == "anywhere"

    def spots_in_base(targets) -> np.ndarray:
        """Where the captures' spots were (layout frame, a measured spot or the aim), in the base frame at
        the sheet's placement: the coach fits the camera's measurements, as solve will."""
        t = np.array(targets, dtype=float).reshape(-1, 3)
        return layout.sheet.to_base(t[:, :2], layout.plane_z) if layout.frame == "sheet" else t

    def coach_data(k: int) -> tuple[np.ndarray, np.ndarray]:
        """The first k captures the coach fits, (k, n) rad and (k, 3) mm base frame. In a camera session a
        capture the camera could not measure enters as spent: its spot where the coach's fit predicts it
        (an aimed spot's residual, at the aiming noise, would be taken for the camera's noise; left out,
        the coach would ask for the same hidden pose again)."""
        q = np.asarray(store.q[:k], dtype=float).reshape(-1, nominal.n)
        spots = spots_in_base(store.target[:k])
        spent = ~np.array(store.measured[:k], bool)
        if camera is not None and spent.any():
            spots[spent] = predict_spots(coach.post.model, q[spent], spots[spent, 2])[0]
        return q, spots

    def coach_status():
        """Refit the coach on every capture so far and print its status block (the prior's with none)."""
        todo = [nm for nm in requested if counts[nm] < opts.per_point]
        q_all = np.asarray(store.q, dtype=float).reshape(len(store.point), nominal.n)
        q_fit, spots = coach_data(len(q_all))
        if len(q_fit):
            coach.update(q_fit, spots)
        aimed = np.array([points[p] for p in store.point]).reshape(-1, 3)  # no suggestion where one was taken
        st = coach.status(q_fit, allowed=todo or None, target=aimed)
        current = q_all[-1] if len(q_all) else robot.read().q
        w("\n".join(coach_lines(st, counts, current, coach.stop_gain, done=not todo)) + "\n")
        return st

    def move_to(q: np.ndarray) -> None:
        """``--guide move``: to q in steps of at most ``max_step``; confirmed before the first move."""
        plan = plan_moves(robot.read().q, q[None], nominal, opts.max_step)
        w(preview(plan))
        if not confirmed[0]:
            confirm(plan, opts.yes, out=out)
            confirmed[0] = True
        for step in plan.steps:
            robot.move_to(step)
        w(
            "  at the suggested pose: the camera measures where the beam lands\n"
            if hands_free and not by_hand
            else "  at the suggested pose: refine the aim by hand, then trigger\n"
        )

    # --guide move with a camera: hands-free, the arm drives itself through the coach's poses and the camera
    # measures each; a pose whose spot it cannot measure is guided by hand once (then kept as aimed)
    hands_free = opts.move and camera is not None
    settled = False  # the camera's exposure, set on the first photo (sessions.exposure)
    by_hand = False
    try:
        robot.connect()
        if robot.guidance and not hands_free:
            w(f"{robot.name}: {robot.guidance}\n")
        t_run = robot.clock.now()
        t_offset = max(store.t, default=0.0)  # the session's t keeps increasing across resumes
        status = None
        if coach is not None:
            # a resumed session: the coach goes through the fits (each warm-started from the one before)
            # that the uninterrupted session made, so its suggestions are the same to the last bit
            for k in range(1, len(store.q)):
                q_fit, spots = coach_data(k)
                if len(q_fit):
                    coach.update(q_fit, spots)
            status = coach_status()
        while True:
            todo = [nm for nm in requested if counts[nm] < opts.per_point]
            if not todo:
                break
            name = todo[0]
            aim = None  # the spot the coach planned off the point: layout frame (2,), base frame (3,), mm
            if status is not None and status.plan.point[0] in todo:
                name = str(status.plan.point[0])
                if anywhere:
                    base = status.plan.target[0]
                    aim = (layout.sheet.from_base(base[None])[0], base)
                if opts.move and not by_hand:
                    move_to(status.suggestion)
                robot.suggest_pose(status.suggestion)
            x, y, z = points[name]
            w("\n" + "\n".join(progress_lines(counts, opts.per_point)) + "\n")
            if hands_free and not by_hand:
                w(f"at {name}: capture {counts[name] + 1} of {opts.per_point}, hands-free  [Ctrl-C stops]\n")
                cmd = "capture"
            else:
                if aim is None:
                    robot.prompt_point(name, points[name], counts[name])
                    where = f"{name} ({x:.1f}, {y:.1f}, {z:.1f}) mm"
                else:
                    robot.prompt_point(name, aim[1], counts[name], spot=aim[0])
                    (sx, sy), (dx, dy) = aim[0], aim[0] - layout.points[name][:2]
                    where = f"({sx:.0f}, {sy:.0f}) mm on the sheet ({dx:+.0f}, {dy:+.0f} mm off {name})"
                w(f"aim at {where}: capture {counts[name] + 1} of {opts.per_point}   [{trigger.hint}]\n")
                cmd = trigger.wait()
            if cmd == "quit":
                w(f"stopped: {saved()}\n")
                return CaptureResult(False, counts, captured, discarded)
            if cmd == "discard":
                gone = store.discard_last()
                if gone is None:
                    w("nothing to discard\n")
                else:
                    if gone in counts:  # a row at a point no longer requested counts nowhere
                        counts[gone] -= 1
                    discarded += 1
                    w(f"discarded the last capture at {gone}\n")
                continue
            state, peak = wait_still(robot, opts.speed_threshold, opts.hold, opts.still_timeout, opts.poll)
            if state is None:
                w(
                    f"the arm did not come to rest within {opts.still_timeout:g} s (max |dq| {peak:.4f} "
                    "rad/s): not captured\n"
                )
                continue
            length = rangefinder.measure() if rangefinder is not None else None
            earlier = np.array([q for p, q in zip(store.point, store.q) if p == name]).reshape(
                -1, len(state.q)
            )
            check = check_capture(
                nominal, points if aim is None else {**points, name: aim[1]}, name, state.q, earlier, opts
            )
            t = t_offset + (state.t - t_run)
            extra = dict(state.extra)
            if length is not None:
                extra["laser_length_measured"] = length
            seen = ""
            if camera is not None:
                # the exposure is settled on the session's first photo, with the laser on a point
                first = None if settled else settle_exposure(camera, readable_by(measure))
                settled = True
                aimed_at = points[name] if aim is None else aim[1]
                cells, seen = spot_cells(store.folder, camera, measure, t, aimed_at, meta, first)
                extra.update(cells)
                if "camera_x" in cells:
                    pass  # measured
                elif hands_free and not by_hand:  # no aim and no measurement: no data
                    w(f"{seen}: not kept; this pose is guided by hand once: aim beside the cross, trigger\n")
                    by_hand = True
                    continue
                else:
                    seen += (
                        ": kept as an aimed capture, fitted to where it was aimed with the aiming noise "
                        "(d Enter discards it, to retake it)\n"
                    )
            by_hand = False
            spot = layout.points[name] + beside  # where it was aimed, layout frame (a sheet's: z 0)
            if aim is not None:
                extra.update(aim_x=aim[0][0], aim_y=aim[0][1])
                spot = np.r_[aim[0], spot[2]]
            if "camera_x" in extra:
                spot = np.r_[extra["camera_x"], extra["camera_y"], spot[2]]
            if layout.frame == "sheet":
                spot = np.r_[spot[:2], layout.plane_z]  # as load_session's target: z the plane's height
            row = {"point": name, "t": t, "q": state.q, "dq": state.dq, "tau": state.tau, "target": spot}
            store.append({**row, **extra})
            counts[name] += 1
            captured += 1
            w("\n".join(_report(check, counts[name], t, peak, length)) + "\n" + seen)
            if check.flag and opts.auto_discard:
                store.discard_last()
                counts[name] -= 1
                discarded += 1
                w("discarded it (the simulated operator heeds the warning)\n")
                continue
            if coach is not None:
                status = coach_status()
                if opts.until_mm is not None and status.predicted <= opts.until_mm:
                    w(
                        f"predicted error at {status.region} {status.predicted:.2f} mm <= --until "
                        f"{opts.until_mm:g} mm: session complete\n"
                    )
                    w(f"session complete: {sum(counts.values())} captures in {store.path}\n")
                    return CaptureResult(True, counts, captured, discarded)
    except KeyboardInterrupt:
        robot.stop()
        w(f"\ninterrupted: the arm was stopped; {saved()}\n")
        raise
    except MotionRefused as e:
        raise MotionRefused(f"{e}; {saved()}") from None
    except RobotConnectionError as e:
        robot.stop()
        raise RobotConnectionError(f"{e}; {saved()}") from None
    except DeviceError as e:
        raise DeviceError(f"{e}; {saved()}") from None
    finally:
        robot.close()
    w("\n" + "\n".join(progress_lines(counts, opts.per_point)) + "\n")
    w(f"session complete: {sum(counts.values())} captures in {store.path}\n")
    return CaptureResult(True, counts, captured, discarded)
