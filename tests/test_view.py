"""The live view (issue 48): what headless Chromium shows of a simulated hands-free session -- set-up,
aiming with the spot outside and inside the target, a hidden spot, the end -- checked against the session's
state and the simulated truth, not only that the page loads; the token; the page's actions, none of which
moves the arm.

The session runs in a thread; a gate (a SessionState whose phase/problem/end calls block at chosen moments)
holds it while the page is read and photographed. Set LASERCAL_SCREENSHOTS=docs/view to keep the
screenshots there (the ones in docs/ were taken so).
"""

from __future__ import annotations

import io
import json
import os
import queue
import re
import shutil
import threading
import time
import urllib.error
import urllib.request
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
try:
    import aiohttp  # noqa: F401
    from playwright.sync_api import sync_playwright
except ImportError:  # pragma: no cover - the test extra brings both
    sync_playwright = None
needs_browser = pytest.mark.skipif(
    CHROMIUM is None or sync_playwright is None,
    reason="the live view's browser test needs Debian's chromium (apt-get install chromium) and the test "
    "extra (aiohttp, playwright)",
)

from lasercal.collector.sessions import start as start_module  # noqa: E402
from lasercal.collector.sessions.settings import capture_settings  # noqa: E402
from lasercal.collector.sessions.start import CaptureGuide, start_capture  # noqa: E402
from lasercal.collector.sessions.state import SessionState  # noqa: E402
from lasercal.collector.view import ViewOptions  # noqa: E402

BROWSER_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync"]  # fmt: skip


class Gated(SessionState):
    """A SessionState that stops the session's thread where the test wants to look (``want``: the names of
    the moments still to be seen); the test releases it."""

    stops: queue.Queue = queue.Queue()
    want: set = set()
    last: SessionState | None = None  # the instance the running session writes

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        Gated.last = self

    def _hold(self, name: str, **what) -> None:
        if name in Gated.want:
            go = threading.Event()
            Gated.stops.put((name, what, go))
            go.wait(600)

    def phase(self, phase, instruction=None, accepts=()):
        super().phase(phase, instruction, accepts)
        if phase == "setup" and instruction and instruction.startswith("the coach fits"):
            self._hold("setup")
        step = re.search(r"step (\d+) of", instruction or "")
        if phase == "moving" and step and int(step.group(1)) >= 2:
            self._hold("outside")
        if phase == "settling":
            self._hold("inside")
        if phase == "captured" and sum(p["done"] for p in self.data["progress"]) == 9:
            self._hold("last")  # the last capture (its count not yet shown): the page discards it

    def problem(self, text, img=None):
        super().problem(text, img)
        if img is not None and "could not measure" in text:
            self._hold("hidden")

    def end(self, summary, phase="done"):
        super().end(summary, phase)
        self._hold("end")


def _get(url: str, token: str | None = None, data: dict | None = None, headers: dict | None = None):
    req = urllib.request.Request(url, method="POST" if data is not None else "GET")
    if token:
        req.add_header("X-Token", token)
    for k, v in (headers or {}).items():
        req.add_header(k, v)
    body = None if data is None else json.dumps(data).encode()
    try:
        with urllib.request.urlopen(req, body, timeout=10) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def _page_state(page) -> dict:
    return page.evaluate(
        """() => ({
        phase: document.getElementById('phase').dataset.phase,
        instruction: document.getElementById('instruction').textContent,
        target: document.getElementById('target').dataset.state || '',
        targetText: document.getElementById('target').textContent,
        progress: [...document.querySelectorAll('#progress .bar')]
            .map(b => [b.dataset.name, +b.dataset.done]),
        problem: document.getElementById('problem').style.display === 'block'
            ? document.getElementById('problemtext').textContent : null,
        problemPhoto: document.getElementById('problemphoto').naturalWidth,
        setup: [...document.querySelectorAll('#setup li')].map(li => li.textContent),
        buttons: [...document.querySelectorAll('#buttons button')]
            .filter(b => !b.disabled).map(b => b.dataset.do),
        seq: window.viewStats.state ? window.viewStats.state.seq : -1,
        frameT: window.viewStats.state && window.viewStats.state.frame.t || 0,
        frameSeq: window.viewStats.lastSeq || 0,
        frames: window.viewStats.frames,
        said: document.getElementById('said').textContent,
    })"""
    )


def _settle(page, state: SessionState, since: float, timeout: float = 120.0) -> tuple[dict, dict]:
    """The page once it shows the state as it is now and a frame the camera gave after ``since`` (s since
    the epoch, when the session stopped at the gate), with the state's snapshot of that moment."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        snap = state.snapshot()
        fresh = snap["frame"].get("t", 0) > since
        shown = _page_state(page)
        if fresh and shown["seq"] >= snap["seq"] and shown["frameSeq"] >= snap["frame"]["seq"]:
            # the page's numbers of the frame it shows are that frame's (they come twice a second)
            while _page_state(page)["frameT"] < snap["frame"]["t"] and time.monotonic() < end:
                time.sleep(0.1)
            shown = _page_state(page)
            # the very frame of the snapshot: the feed goes on while the session waits at the gate, and a
            # newer frame's verdict may differ (the page showed 'inside' beside the snapshot's 'outside')
            if shown["frameSeq"] == snap["frame"]["seq"]:
                return shown, snap
            continue
        time.sleep(0.2)
    raise AssertionError(f"the page did not catch up: {shown}")


def _true_spot_on_sheet(started) -> np.ndarray:
    """Where the simulated true beam meets the sheet now, in the sheet's frame (mm): the ground truth the
    page's inside / outside is checked against."""
    layout = started.settings.layout
    spot, _ = started.robot.true_spot(layout.plane_z)
    return layout.sheet.from_base(spot[None, :2])[0]


@needs_browser
def test_the_page_shows_a_hands_free_session_as_it_is(sheet, tmp_path, monkeypatch):
    monkeypatch.setattr(start_module, "SessionState", Gated)
    # the page's view of a spot the camera could not measure ('hidden') needs one: since issue 53 the coach
    # plans for the camera's view and this session (seed 0) meets none, so its planning is left out here
    from lasercal.solver.analysis.design import Coach

    monkeypatch.setattr(Coach, "see_from", lambda self, *a, **k: 0)
    Gated.want = {"setup", "outside", "inside", "hidden", "last", "end"}
    given = {"backend": "fake", "per_point": 2, "camera": "fake", "aim_noise": 3.0, "seed": 0}
    started = start_capture(
        capture_settings(given, str(sheet), str(tmp_path / "s")), CaptureGuide(auto=True, move=True, yes=True)
    )
    out = io.StringIO()
    # who released each move: the last of the terminal's commands (the command line's --yes at the start,
    # the simulated operator's trigger after) and the page's accepted presses before it
    log, moves = ["terminal"], []
    real_move = started.robot.move_to
    started.robot.move_to = lambda q: (moves.append(log[-1]), real_move(q))[1]
    started = replace(started, trigger=Logged(started.trigger, log))
    result = {}
    session = threading.Thread(
        target=lambda: result.update(r=started.run(out, ViewOptions(port=0, fps=8))),
        name="session",
        daemon=True,
    )
    session.start()
    shots = Path(os.environ.get("LASERCAL_SCREENSHOTS") or tmp_path / "shots")
    shots.mkdir(parents=True, exist_ok=True)
    seen = {}
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=BROWSER_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 820})
        url = None
        while Gated.want:
            name, _, go = Gated.stops.get(timeout=900)
            since = time.time()
            state = Gated.last
            if url is None:
                url = re.search(r"live view: (http://\S+)", out.getvalue()).group(1)
                base, token = url.split("?token=")
                # the token: a request without it (or with another) is refused, with it served
                assert _get(base + "state")[0] == 403
                assert _get(base + "state?token=x" + token)[0] == 403
                assert _get(base + "action", None, {"do": "stop"})[0] == 403
                assert _get(url.replace("/?", "/state?"))[0] == 200
                page.goto(url)
            if name == "outside":  # moving: the page may stop the session, not capture or discard
                assert _get(base + "action", token, {"do": "capture"})[0] == 409
                assert _get(base + "action", token, {"do": "discard"})[0] == 409
            if name == "last":  # the page discards the last capture: the retake's move is the terminal's
                assert _get(base + "action", token, {"do": "discard"})[0] == 200
                log.append("page")
                Gated.want.discard(name)
                go.set()
                continue
            shown, snap = _settle(page, state, since)
            frame = snap["frame"]
            # what the page shows is the session's state
            assert shown["phase"] == snap["phase"] and shown["instruction"] == snap["instruction"]
            assert shown["progress"] == [[p["name"], p["done"]] for p in snap["progress"]]
            assert sorted(shown["buttons"]) == snap["actions"]
            if name in ("outside", "inside"):
                truth = np.hypot(*(_true_spot_on_sheet(started) - np.asarray(snap["target"]["xy"])))
                tol = snap["target"]["tol_mm"]
                want = "inside" if name == "inside" else "outside"
                assert (
                    shown["target"] == {True: "inside", False: "outside", None: "nospot"}[frame.get("inside")]
                )
                if frame.get("inside") is None or shown["target"] != want or abs(truth - tol) < 1.5:
                    go.set()  # not this one (the spot hidden, or too near the circle's edge to judge)
                    continue
                # the page's verdict is the simulated truth's: the true spot within the circle or not
                assert (truth <= tol) == (name == "inside"), (truth, tol)
                assert f"spot {want} the target" in shown["targetText"]
                assert abs(frame["off_mm"] - truth) < 1.5, (frame["off_mm"], truth)  # the live spot, ~1 mm
            if name == "setup":
                assert shown["setup"][0] == "markers: 6 of 6 read" and frame["markers_read"] == 6
                assert re.match(r"sheet: 0\.\d\d mm/px", shown["setup"][1]) and frame["mm_per_px"] <= 0.5
                assert any(s.startswith("clipped: ") for s in shown["setup"])
            if name == "hidden":
                assert shown["problem"] == snap["problem"]["text"] and "could not measure" in shown["problem"]
                page.wait_for_function(
                    "document.getElementById('problemphoto').naturalWidth > 0", timeout=30000
                )
                assert frame.get("inside") is None  # the arm hides the spot from the live frames too
            if name == "end":
                assert shown["phase"] == "done" and "session complete: 10 captures" in shown["instruction"]
                assert not shown["buttons"]
            page.screenshot(path=str(shots / f"{name}.png"))
            seen[name] = shown
            Gated.want.discard(name)
            go.set()
        browser.close()
    session.join(600)
    # the page's buttons: capture is refused hands-free (the camera captures), and nothing it asks moves
    # the arm: after its discard of the last capture, the retake's move waited for the terminal (here the
    # simulated operator's trigger); old code moved at once, released by the page
    assert result["r"].complete and "discarded the last capture at" in out.getvalue()
    assert len(moves) > 10 and set(moves) == {"terminal"}, moves
    assert set(seen) == {"setup", "outside", "inside", "hidden", "end"}


class Logged:
    """A trigger whose every command is logged as the terminal's (who released the moves after it)."""

    def __init__(self, trigger, log: list):
        self.trigger, self.log, self.hint = trigger, log, trigger.hint

    def wait(self) -> str:
        cmd = self.trigger.wait()
        self.log.append("terminal")
        return cmd

    def close(self) -> None:
        self.trigger.close()


class Typed:
    """The terminal's trigger, typed by the test; each command it gives is logged as the terminal's."""

    hint = "the test's terminal"

    def __init__(self, log: list):
        self.log, self.typed = log, queue.Queue()

    def wait(self) -> str:
        cmd = self.typed.get()
        self.log.append("terminal")
        return cmd

    def close(self) -> None:
        """Nothing to release."""


@pytest.mark.skipif(sync_playwright is None, reason="the live view needs the test extra's aiohttp")
def test_the_pages_three_actions_drive_a_hand_guided_session_and_move_nothing(tmp_path):
    """Hand-guided with --guide move (the arm goes to each suggested pose, the operator refines by hand):
    the page's capture now captures, discard the last removes it, stop ends the session, resumable; none
    moves the arm -- after the page's capture or discard the next move waits for the terminal, which
    releases it (recorded: who released each move); an action the session cannot take is refused with the
    reason, and the ended session leaves nothing serving."""
    from lasercal.solver.formats.session import load_session

    given = {"backend": "fake", "per_point": 2, "aim_noise": 1.0, "seed": 1}
    started = start_capture(
        capture_settings(given, "thesis", str(tmp_path / "s")), CaptureGuide(auto=False, move=True)
    )
    log, moves = ["terminal"], []  # the command line released the first move
    terminal = Typed(log)
    started = replace(started, trigger=terminal)
    real_move = started.robot.move_to
    started.robot.move_to = lambda q: (moves.append(log[-1]), real_move(q))[1]
    out = io.StringIO()
    result = {}
    session = threading.Thread(
        target=lambda: result.update(r=started.run(out, ViewOptions(port=0))), daemon=True, name="session"
    )
    session.start()
    while "live view: " not in out.getvalue():
        time.sleep(0.05)
    url = re.search(r"live view: (http://\S+)", out.getvalue()).group(1)
    base, token = url.split("?token=")

    def when(check, timeout=120.0) -> dict:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            s = json.loads(_get(base + "state", token)[1])
            if check(s):
                return s
            time.sleep(0.05)
        raise AssertionError(s)

    def done(s) -> int:
        return sum(p["done"] for p in s["progress"])

    def page(action):
        got = _get(base + "action", token, {"do": action})
        if got[0] == 200:
            log.append("page")
        return got

    when(lambda s: s["phase"] == "aiming")
    assert moves and set(moves) == {"terminal"}
    for k, action in enumerate(["capture"] * 3 + ["discard"]):
        before = len(moves)
        assert page(action) == (200, b'{"ok": true, "queued": "%s"}' % action.encode())
        want = 2 if action == "discard" else k + 1
        # the press is taken where the arm is; then the session waits for the terminal (no move)
        s = when(lambda s, b=before: s["phase"] == "confirm" or len(moves) > b)
        assert len(moves) == before and done(s) == want and s["actions"] == ["stop"], (moves, s)
        terminal.typed.put("capture")  # the terminal releases the move to the next pose
        when(lambda s, b=before: s["phase"] == "aiming" and len(moves) > b)
    assert "discarded the last capture at" in out.getvalue()
    assert page("jump")[0] == 409  # not one of the three
    assert page("stop")[0] == 200
    session.join(120)
    assert not result["r"].complete and load_session(tmp_path / "s").m == 2
    assert len(moves) > 4 and set(moves) == {"terminal"}, moves  # the page released no move
    assert "stopped: 2 captures are safe" in out.getvalue()
    with pytest.raises(OSError):  # the session ended: nothing serves any more, nothing is left behind
        urllib.request.urlopen(base + "state?token=" + token, timeout=5)


@pytest.mark.skipif(sync_playwright is None, reason="the live view needs the test extra's aiohttp")
def test_a_view_that_cannot_be_served_leaves_no_session_behind(tmp_path, capsys):
    """The view's port taken: one line naming it, exit 2, and the new session's folder is not left."""
    import socket

    from lasercal.collector.cli.main import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        argv = ["capture", "--layout", "thesis", "--backend", "fake", "--auto", "--per-point", "1",
                "--no-coach", "--view", "--view-port", str(port), "-o", str(tmp_path / "s")]  # fmt: skip
        assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--view: cannot serve on 127.0.0.1:{port}" in err[0]
    assert not (tmp_path / "s").exists()
