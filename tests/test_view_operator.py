"""The operator's side of the live view (issue 53): a page press never releases a move the person at the
robot did not confirm; stop is taken in every phase (validate too, between the steps of one
configuration); the view opened from another device through the machine's own non-loopback address, with
the token in the printed link, the page's token form without it, and a malformed token refused.

A test double wraps the fake backend and records who released each move: the terminal (the command line
that started the session, or its trigger's command) or the page (its last accepted press).
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import socket
import subprocess
import threading
import time
from dataclasses import replace

import pytest

try:
    import aiohttp  # noqa: F401
except ImportError:  # pragma: no cover - the test extra brings it
    aiohttp = None
try:
    from playwright.sync_api import sync_playwright
except ImportError:  # pragma: no cover
    sync_playwright = None

from lasercal.collector.sessions.settings import capture_settings  # noqa: E402
from lasercal.collector.sessions.start import CaptureGuide, start_capture  # noqa: E402
from lasercal.collector.sessions.state import PHASES, SessionState  # noqa: E402
from lasercal.collector.view import ViewOptions  # noqa: E402
from tests.test_view import Typed as Terminal  # noqa: E402  (the terminal the test types into)
from tests.test_view import _get  # noqa: E402

needs_view = pytest.mark.skipif(aiohttp is None, reason="the live view needs the test extra's aiohttp")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
BROWSER_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync"]  # fmt: skip


class Releases:
    """The fake backend, wrapped: every ``move_to`` is recorded with who released it -- the last of the
    events the terminal and the page gave (``log``), 'terminal' at the start (the command line)."""

    def __init__(self, robot, log: list):
        self._robot, self.log, self.moves = robot, log, []

    def move_to(self, q):
        self.moves.append(self.log[-1])
        return self._robot.move_to(q)

    def __getattr__(self, name):
        return getattr(self._robot, name)


def _session(started, out, **view):
    result = {}
    thread = threading.Thread(
        target=lambda: result.update(r=started.run(out, ViewOptions(port=0, **view))),
        daemon=True,
        name="session",
    )
    thread.start()
    end = time.monotonic() + 120
    while "live view: " not in out.getvalue():
        assert time.monotonic() < end and thread.is_alive(), out.getvalue()
        time.sleep(0.05)
    url = re.search(r"live view: (http://\S+)", out.getvalue()).group(1)
    return thread, result, url


@needs_view
def test_a_page_press_never_releases_a_move(sheet, tmp_path):
    """Hand-guided with --guide move (the issue's session): the page's capture and discard act where the
    arm is; the move to the next pose waits until the terminal releases it. Old code: the page's capture
    moved the arm at once (the terminal had confirmed once per session)."""
    from lasercal.solver.formats.session import load_session

    log = ["terminal"]  # the session starts from the command line
    given = {"backend": "fake", "per_point": 2, "aim_noise": 1.0, "seed": 3}
    started = start_capture(
        capture_settings(given, str(sheet), str(tmp_path / "s")), CaptureGuide(auto=False, move=True)
    )
    robot, terminal = Releases(started.robot, log), Terminal(log)
    started = replace(started, robot=robot, trigger=terminal)
    out = io.StringIO()
    session, result, url = _session(started, out)
    base, token = url.split("?token=")

    def state() -> dict:
        return json.loads(_get(base + "state", token)[1])

    def when(check, timeout=180.0) -> dict:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            s = state()
            if check(s):
                return s
            time.sleep(0.05)
        raise AssertionError(s)

    def page(action: str) -> int:
        code = _get(base + "action", token, {"do": action})[0]
        if code == 200:
            log.append("page")
        return code

    when(lambda s: s["phase"] == "aiming")
    first = len(robot.moves)
    assert first > 0 and set(robot.moves) == {"terminal"}  # the first pose: the command line's
    for action in ("capture", "discard"):
        before = len(robot.moves)
        assert page(action) == 200
        # the session takes the press, then waits: no move (old code: the arm moved to the next pose)
        s = when(lambda s, b=before: s["phase"] == "confirm" or len(robot.moves) > b)
        time.sleep(1.0)
        assert robot.moves.count("page") == 0, f"the page's {action} released a move: {robot.moves}"
        assert s["phase"] == "confirm" and s["actions"] == ["stop"] and len(robot.moves) == before
        assert page("capture") == 409 and page("discard") == 409  # nothing else from the page meanwhile
        terminal.typed.put("capture")  # the person at the robot releases this one move
        when(lambda s, b=before: s["phase"] == "aiming" and len(robot.moves) > b)
    assert "the move to the next pose waits for the terminal" in out.getvalue()
    assert page("stop") == 200
    session.join(120)
    assert not session.is_alive() and not result["r"].complete
    assert len(robot.moves) > first and set(robot.moves) == {"terminal"}, robot.moves
    assert load_session(tmp_path / "s").m == 0  # the page's capture, then its discard


def test_stop_is_accepted_in_every_phase():
    """The page's stop is queued whatever the phase (old code: refused while setting up, photographing,
    ...), stays asked for every safe point after, and is refused only once the session ended."""
    for phase in PHASES:
        st = SessionState("capture")
        st.phase(phase, "", ())
        assert st.post("stop") is None, phase
        assert "stop" in st.snapshot()["actions"]
        assert st.take() == "stop" and st.take() == "stop" and st.stop_asked()
        assert st.post("capture") is not None  # capture and discard only where the phase takes them
    st = SessionState("capture")
    st.end("done")
    assert st.snapshot()["actions"] == []


@needs_view
def test_the_pages_stop_while_setting_up_stops_before_any_move(sheet, tmp_path):
    """A stop asked while the coach designs the session (about 20 s, phase 'setting up') is accepted and
    taken at the first safe point: no move, no capture, resumable."""
    log = ["terminal"]
    given = {"backend": "fake", "per_point": 2, "aim_noise": 1.0, "seed": 4}
    started = start_capture(
        capture_settings(given, str(sheet), str(tmp_path / "s")), CaptureGuide(auto=True, move=True)
    )
    robot = Releases(started.robot, log)
    out = io.StringIO()
    session, result, url = _session(replace(started, robot=robot), out)
    base, token = url.split("?token=")
    phase = json.loads(_get(base + "state", token)[1])["phase"]
    assert _get(base + "action", token, {"do": "stop"}) == (200, b'{"ok": true, "queued": "stop"}'), phase
    session.join(180)
    assert not result["r"].complete and not robot.moves
    assert "stopped: 0 captures are safe" in out.getvalue()


@needs_view
def test_validate_takes_the_pages_stop_between_the_steps_of_one_configuration(tmp_path):
    """The arm moves to each configuration in steps of at most --max-step: a stop asked during the first
    step is taken before the second (old code: every step of the configuration, then the stop)."""
    from lasercal.collector.sessions.settings import validate_settings
    from lasercal.collector.sessions.start import start_validation

    settings = validate_settings(
        {"backend": "fake"}, "panda", str(tmp_path / "v"), layout="thesis", point="P4", n=3, max_step=0.02
    )
    started = start_validation(settings)
    urls = []

    class StopOnFirstStep:
        def __init__(self, robot):
            self._robot, self.steps = robot, 0

        def move_to(self, q):
            self.steps += 1
            if self.steps == 1:  # the page's stop, asked while the arm makes its first step
                base, token = urls[0].split("?token=")
                assert _get(base + "action", token, {"do": "stop"})[0] == 200
            return self._robot.move_to(q)

        def __getattr__(self, name):
            return getattr(self._robot, name)

    robot = StopOnFirstStep(started.robot)
    plan_steps = []
    out = io.StringIO()

    class Out(io.StringIO):
        def write(self, text):
            found = re.search(r"live view: (http://\S+)", text)
            if found:
                urls.append(found.group(1))
            plan_steps.extend(int(m) for m in re.findall(r"in (\d+) moves", text))
            out.write(text)
            return len(text)

    res = replace(started, robot=robot).run(Out(), ViewOptions(port=0))
    assert plan_steps and plan_steps[0] > 3  # several steps per configuration
    assert robot.steps == 1, robot.steps
    assert not res.complete and res.photos == 0
    assert "stopped after 0 photos" in out.getvalue()


def _non_loopback_address() -> str | None:
    """One of this machine's own non-loopback IPv4 addresses; as root with none, a dummy interface's
    (10.213.0.1 on lc0, made here: an address on this machine only)."""

    def own() -> list[str]:  # found independently of lasercal's own search: the kernel's, through ip
        if not shutil.which("ip"):
            return []
        text = subprocess.run(["ip", "-o", "-4", "addr", "show"], capture_output=True, text=True).stdout
        return [a for a in re.findall(r"inet (\d+\.\d+\.\d+\.\d+)/", text) if not a.startswith("127.")]

    found = own()
    if not found and os.geteuid() == 0 and shutil.which("ip"):
        for cmd in (["ip", "link", "add", "lc0", "type", "dummy"], ["ip", "addr", "add", "10.213.0.1/24",
                    "dev", "lc0"], ["ip", "link", "set", "lc0", "up"]):  # fmt: skip
            subprocess.run(cmd, capture_output=True, check=False)
        found = own()
    return found[0] if found else None


class Never:
    hint = "nobody"

    def wait(self) -> str:
        threading.Event().wait()

    def close(self) -> None:
        """Nothing to release."""


@needs_view
@pytest.mark.skipif(
    CHROMIUM is None or sync_playwright is None, reason="needs Debian's chromium and playwright"
)
def test_another_device_opens_the_view_on_the_machines_own_address(tmp_path):
    """--view-host 0.0.0.0: every link printed is a non-loopback address of this machine with the token
    (not 0.0.0.0); headless Chromium opens it through that address. Without the token the page's form, and
    nothing of the run; the API stays 403; a malformed token is a 403, not a 500; typed into the form,
    the token opens the page, whose stop ends the session."""
    address = _non_loopback_address()
    if address is None:  # pragma: no cover - every CI machine (root, or a network) has one
        pytest.skip("this machine has no non-loopback address and cannot make one (not root)")
    given = {"backend": "fake", "per_point": 2, "aim_noise": 1.0, "seed": 1}
    started = start_capture(
        capture_settings(given, "thesis", str(tmp_path / "s")), CaptureGuide(auto=False, coach=False)
    )
    out = io.StringIO()
    session, result, _ = _session(replace(started, trigger=Never()), out, host="0.0.0.0")
    links = re.findall(r"live view: (http://\S+)", out.getvalue())
    assert links and not any("0.0.0.0" in u or "127.0.0.1" in u for u in links), out.getvalue()
    assert all(re.fullmatch(r"http://[\d.]+:\d+/\?token=[\w-]+", u) for u in links)
    url = next(u for u in links if f"//{address}:" in u)
    base, token = url.split("?token=")
    # without the token: the page's form and nothing else; the API refused; malformed tokens refused
    code, html = _get(base)
    assert code == 200 and b'id="tokenform"' in html and token.encode() not in html
    for path in ("state", "events", "frame", "problem.jpg", "state?token=%C3%A9", "state?token=%FF%FE"):
        assert _get(base + path)[0] == 403, path
    assert _get(base + "action", None, {"do": "stop"})[0] == 403
    assert _get(base + "?token=%C3%A9")[0] == 200  # the form again
    with socket.create_connection((address, int(base.rsplit(":", 1)[1].strip("/")))) as raw:
        raw.sendall(b"GET /state HTTP/1.1\r\nHost: x\r\nX-Token: \xc3\xa9\xff\r\nConnection: close\r\n\r\n")
        reply = b""
        while chunk := raw.recv(4096):
            reply += chunk
    assert reply.startswith(b"HTTP/1.1 403"), reply[:80]
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=BROWSER_ARGS)
        page = browser.new_page()
        page.goto(base)
        assert page.is_visible("#tokenform") and not page.is_visible("#main")
        page.fill("#tokeninput", "not-" + token)
        page.click("#tokenform button")
        page.wait_for_function("document.getElementById('tokenwhy').textContent.includes('not this run')")
        assert not page.is_visible("#main")
        page.fill("#tokeninput", token)
        page.click("#tokenform button")
        page.wait_for_function("document.getElementById('phase').dataset.phase === 'aiming'", timeout=60000)
        assert page.is_visible("#main") and not page.is_visible("#tokenform")
        assert page.evaluate("location.hostname") == address
        page.click("#stop")
        page.wait_for_function("document.getElementById('phase').dataset.phase === 'stopped'", timeout=60000)
        browser.close()
    session.join(60)
    assert not result["r"].complete and "stopped: 0 captures are safe" in out.getvalue()
