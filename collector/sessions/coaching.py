"""The coach's part of a capture session: its status block, the coach a session starts with, and the run's
coach and move steps (:class:`CoachSteps`, a part of :class:`~collector.sessions.capture.CaptureRun`): the
coach's refit after each capture, and ``--guide move``'s moves to the pose it suggests."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.collector.report.text import identifiable_text
from lasercal.collector.sessions.anywhere import CAMERA_NOISE_MM
from lasercal.collector.sessions.motion import confirm, plan_moves, preview
from lasercal.collector.sessions.state import ACTIONS, SessionState
from lasercal.collector.sessions.store import CaptureStore
from lasercal.solver.formats.session import Layout
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.model import RobotModel

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
    return Coach(
        model,
        layout,
        cfg["seed"],
        tol,
        sheet=sheet is not None,
        anywhere=anywhere,
        pose=sheet,
        effects=bool(cfg.get("plan_effects")),
    )


EYE_FILE = "camera_eye.yaml"  # where the camera stands, as the first measured photo's markers said


def recorded_view(folder, eye, in_view=()) -> tuple[np.ndarray | None, tuple]:
    """The camera's eye and the markers in its view a session recorded (:data:`EYE_FILE`), else ``eye``
    (layout frame, mm) and ``in_view`` (marker ids), recorded now: a resumed session plans for the camera
    its first photo found, as the uninterrupted one did. A file without ``markers_in_view`` (an older
    session) holds every marker in view."""
    from lasercal.collector.sessions.store import write_atomic
    from lasercal.solver.formats.robots import load_yaml

    path = Path(folder) / EYE_FILE
    if path.is_file():
        got = load_yaml(path)
        return np.asarray(got["eye_mm"], dtype=float), tuple(int(i) for i in got.get("markers_in_view") or ())
    if eye is None:
        return None, ()
    write_atomic(
        path,
        "# where the camera stands, mm, in the layout's frame, and the markers in its view (ids): from the\n"
        "# first measured photo's markers\n"
        f"eye_mm: [{eye[0]:.3f}, {eye[1]:.3f}, {eye[2]:.3f}]\n"
        f"markers_in_view: [{', '.join(str(int(i)) for i in in_view)}]\n",
    )
    return np.asarray(eye, dtype=float), tuple(int(i) for i in in_view)


class CoachSteps:
    """The coach's and the moves' steps of a capture run (:class:`~collector.sessions.capture.CaptureRun`,
    whose state they read: the store, the robot, the coach, the layout and its points, the counts, the
    session state).
    """

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

    def sight_from(self, eye, in_view=()) -> None:
        """Once a photo's markers tell where the camera stands (``eye``, layout frame, mm: eq. V2), the
        coach plans only poses whose spot and enough markers that camera sees past the arm (eq. V1,
        :meth:`solver.analysis.design.Coach.see_from`), and says so once. Only the markers that photo
        found (``in_view``, ids; empty: all) count: a marker out of the camera's frame is never seen."""
        if self.coach is None or self.sighted or self.layout.frame != "sheet":
            return
        eye, in_view = recorded_view(self.store.folder, eye, in_view)
        if eye is None:
            return
        from lasercal.collector.sessions.anywhere import session_layout_file
        from lasercal.vision.plane import load_markers

        markers = load_markers(session_layout_file(self.meta.get("collector", {}), self.store.folder))
        if markers is None:
            return
        lay = self.layout
        ids = [i for i in markers.corners if not in_view or int(i) in in_view]
        corners = np.array([np.asarray(markers.corners[i], dtype=float) for i in ids])  # (k, 4, 2)
        base = lay.sheet.to_base(corners.reshape(-1, 2), lay.plane_z).reshape(*corners.shape[:2], 3)
        at = lay.sheet.to_base(np.asarray(eye, dtype=float)[None, :2], lay.plane_z)[0] + np.r_[0, 0, eye[2]]
        need = min(markers.min_markers + 1, len(corners))
        aside = self.coach.see_from(at, base, need)
        self.sighted = True
        self.say(
            f"  coach: the camera stands at ({at[0]:.0f}, {at[1]:.0f}, {at[2]:.0f}) mm (from the markers); "
            f"{aside} of its {len(self.coach.cand.q)} candidate poses hide the spot or leave fewer than "
            f"{need} markers in its view: not planned\n"
        )

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


class StateStream:
    """A text stream that says through a SessionState (what :func:`motion.confirm` prints)."""

    def __init__(self, state: SessionState):
        self.state = state

    def write(self, text: str) -> None:
        self.state.say(text)

    def flush(self) -> None:
        """Nothing buffered."""
