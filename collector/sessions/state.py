"""What a session is doing now: the one source of truth that the terminal and the live view both read.

A capture or validation session (:mod:`sessions.capture`, :mod:`sessions.validate`) is a small state
machine; each step writes here what the operator should know -- the phase, the instruction, each point's
progress, the last capture's measured spot and residual, the coach's prediction and stop rule, the
standstill countdown, what went wrong -- and says its lines through :meth:`SessionState.say`. The terminal
is a listener that prints those lines; the live view (``--view``, :mod:`collector.view`) serves
:meth:`SessionState.snapshot` and its frames. The view posts only three actions (:data:`ACTIONS`), which
the machine takes at its own safe points (:meth:`SessionState.take`): nothing here moves the arm. A stop is
accepted in every phase and stays asked (:meth:`SessionState.stop_asked`): the machine ends at its next
safe point (before a move, between two steps of a move, at a trigger, before a photo).
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

# the phases of a session, in words the page shows
PHASES = {
    "setup": "setting up",
    "confirm": "waiting for the terminal's confirmation",
    "moving": "moving",
    "aiming": "aiming",
    "settling": "waiting for the arm to be still",
    "photo": "photographing",
    "captured": "captured",
    "problem": "a problem",
    "done": "done",
    "stopped": "stopped",
}
ACTIONS = ("capture", "discard", "stop")  # the only things the page can ask; none moves the arm
LOG_LINES = 60  # the terminal lines the page shows


@dataclass(frozen=True)
class Target:
    """Where the spot should land: ``xy`` in the layout's frame (a sheet's own), mm, within ``tol_mm``."""

    xy: tuple
    tol_mm: float
    label: str


class SessionState:
    """The state of one session, written by its machine (one thread) and read by the terminal and the view.

    Parameters
    ----------
    kind : str, 'capture', 'validation' or 'beam-check'
    out : text stream or None, the terminal: every line said is written to it at once
    """

    def __init__(self, kind: str, out=None):
        self.kind = kind
        self._lock = threading.Condition()
        self._out = out
        self._actions: queue.Queue = queue.Queue()
        self._accepts: set = set()
        self._stop = threading.Event()  # the page asked to stop: taken at the machine's next safe point
        self.seq = 0
        self.data: dict = {
            "kind": kind,
            "phase": "setup",
            "instruction": "",
            "progress": [],
            "last": None,
            "coach": None,
            "standstill": None,
            "target": None,
            "problem": None,
            "log": deque(maxlen=LOG_LINES),
            "ended": False,
            "summary": "",
        }
        self.frame_info: dict = {}  # the live view's analysis of its latest frame (collector.view.live)
        self.problem_jpeg: bytes | None = None  # the photo that showed what went wrong, JPEG

    # ------------------------------------------------------------------ written by the machine
    def say(self, text: str) -> None:
        """Say ``text`` (one or more lines) on the terminal, and keep it for the page."""
        if self._out is not None:
            self._out.write(text)
        with self._lock:
            for line in text.splitlines():
                if line.strip():
                    self.data["log"].append(line)
            self._changed()

    def update(self, **fields) -> None:
        """Set fields of the state (``phase``, ``instruction``, ``progress``, ``last``, ``coach``, ...)."""
        with self._lock:
            self.data.update(fields)
            self._changed()

    def phase(self, phase: str, instruction: str | None = None, accepts=()) -> None:
        """Enter ``phase`` (a key of :data:`PHASES`), with what the operator should do, and the page's
        actions the machine takes in it (:data:`ACTIONS`)."""
        with self._lock:
            self.data["phase"] = phase
            if instruction is not None:
                self.data["instruction"] = instruction
            self._accepts = set(accepts)
            self._changed()

    def problem(self, text: str, img: np.ndarray | None = None) -> None:
        """What went wrong, in words, with the photo that showed it (kept in memory as a JPEG)."""
        jpeg = None
        if img is not None:
            import cv2

            jpeg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])[1].tobytes()
        with self._lock:
            self.problem_jpeg = jpeg
            self.data["problem"] = {"text": text, "photo": jpeg is not None, "at": self.seq + 1}
            self._changed()

    def end(self, summary: str, phase: str = "done") -> None:
        """The session ended: nothing more is taken from the page."""
        with self._lock:
            self.data.update(phase=phase, ended=True, summary=summary, instruction=summary, standstill=None)
            self._accepts = set()
            self._changed()

    def _changed(self) -> None:
        self.seq += 1
        self._lock.notify_all()

    # ------------------------------------------------------------------ the page's actions
    def accepts(self, action: str) -> bool:
        """Whether the machine takes ``action`` in its present phase."""
        with self._lock:
            return action in self._accepts

    def post(self, action: str) -> str | None:
        """The page asks for ``action``: queued for the machine, or the reason it is refused now. A stop is
        accepted in every phase (the machine ends at its next safe point); capture and discard only in the
        phases that take them."""
        with self._lock:
            if action not in ACTIONS:
                return f"unknown action {action!r} (expected {', '.join(ACTIONS)})"
            if action == "stop":
                if not self._stop.is_set():
                    self._stop.set()
                    self.data["log"].append("[view] stop asked from the page: taken at the next safe point")
                    self._changed()
                return None
            if action not in self._accepts:
                return f"{action} is not possible while {PHASES[self.data['phase']]}"
            self._actions.put(action)
            self.data["log"].append(f"[view] {action} asked from the page")
            self._changed()
        return None

    def stop_asked(self) -> bool:
        """Whether the page asked to stop (it stays asked: every safe point after it sees it)."""
        return self._stop.is_set()

    def take(self, timeout: float | None = 0.0) -> str | None:
        """The next action the page asked for, or None (waits up to ``timeout`` s; None: forever). A stop,
        once asked, comes before anything else, every time."""
        if self._stop.is_set():
            return "stop"
        try:
            return self._actions.get(timeout=timeout) if timeout != 0 else self._actions.get_nowait()
        except queue.Empty:
            return None

    # ------------------------------------------------------------------ read by the view
    def snapshot(self) -> dict:
        """A JSON-able copy of the state, with the live frame's analysis and the accepted actions."""
        with self._lock:
            out = {k: (list(v) if isinstance(v, deque) else v) for k, v in self.data.items()}
            accepts = self._accepts | ({"stop"} if not self.data["ended"] else set())  # stop: always
            out.update(seq=self.seq, actions=sorted(accepts), frame=dict(self.frame_info))
            out["phase_words"] = PHASES[out["phase"]]
        return out

    def wait_change(self, seq: int, timeout: float) -> int:
        """Block until the state's ``seq`` passes ``seq`` (or ``timeout`` s); the present ``seq``."""
        end = time.monotonic() + timeout
        with self._lock:
            while self.seq <= seq and time.monotonic() < end:
                self._lock.wait(max(end - time.monotonic(), 0.0))
            return self.seq

    def set_frame_info(self, info: dict) -> None:
        """The live view's analysis of its latest frame (not a change the page must be woken for)."""
        with self._lock:
            self.frame_info = info


class EitherTrigger:
    """A trigger that also takes the page's actions: ``wait`` returns whichever comes first, the device's
    command (Enter, pedal, pilot button, the simulated operator) or the page's capture / discard / stop.

    The device's ``wait`` blocks (a keyboard's read), so it runs in a helper thread; a command it gives
    after the page's is kept for the next ``wait``, as a device queues a double press. ``source`` says
    where the last command came from: ``"terminal"`` (the device) or ``"page"``.
    """

    def __init__(self, trigger, state: SessionState):
        self.trigger, self.state, self.hint = trigger, state, trigger.hint
        self._device: queue.Queue = queue.Queue()
        self._waiting = False
        self.source = "terminal"

    def _read(self) -> None:
        try:
            self._device.put(self.trigger.wait())
        except BaseException as e:  # a lost device: raised in the session's thread
            self._device.put(e)

    def wait(self, page: bool = True) -> str:
        """The next command: the device's, or (``page``) the page's capture / discard / stop; with
        ``page=False`` only the device's, or the page's stop (``quit``)."""
        if not self._waiting:
            self._waiting = True
            threading.Thread(target=self._read, daemon=True, name="trigger").start()
        while True:
            try:
                cmd = self._device.get(timeout=0.05)
            except queue.Empty:
                if self.state.stop_asked():
                    self.source = "page"
                    return "quit"
                asked = self.state.take() if page else None
                if asked is not None:
                    self.source = "page"
                    return "quit" if asked == "stop" else asked
                continue
            self._waiting = False
            if isinstance(cmd, BaseException):
                raise cmd
            self.source = "terminal"
            return cmd

    def wait_terminal(self) -> str:
        """The device's next command (the terminal's), or ``quit`` when the page asked to stop."""
        return self.wait(page=False)

    def close(self) -> None:
        self.trigger.close()
