"""Triggers (serial over loop:// and socket://, pilot buttons, keyboard) and the serial rangefinder."""

from __future__ import annotations

import io
import socket
import threading
import time

import pytest
import serial

from lasercal.collector.errors import DeviceError, InputEnded
from lasercal.collector.hardware.base import FakeClock
from lasercal.collector.hardware.franky import FrankyPilot
from lasercal.collector.hardware.rangefinder import SerialRangefinder, parse_reading
from lasercal.collector.hardware.triggers import EnterTrigger, PilotTrigger, SerialTrigger, make_trigger
from lasercal.collector.sessions.capture import CaptureOptions, run_capture
from lasercal.collector.sessions.store import CaptureStore
from lasercal.collector.worlds.fake import FakeOperator, FakeRobot
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session, session_meta

LAYOUT = load_layout(builtin_dir("layouts") / "thesis.yaml")
TRUTH = load_model("panda_thesis_identified")


def _fake_robot(per_point: int) -> FakeRobot:
    pts = {k: LAYOUT.points[k] for k in LAYOUT.calibration}
    return FakeRobot(TRUTH, FakeClock(), FakeOperator(TRUTH, pts, per_point, 1.0, 0, LAYOUT.aim_kwargs()))


def test_serial_button_box_over_loop_drives_a_session(tmp_path):
    port = serial.serial_for_url("loop://", timeout=0.05)
    port.write(b"CAPTURE\nhello\r\ncapture\r\nDISCARD\nCAPTURE\nQUIT\n")  # what a pedal would have sent
    out = io.StringIO()
    robot = _fake_robot(5)
    store = CaptureStore.create(tmp_path / "s", session_meta("panda", LAYOUT, 825.0), 7, robot.extra_columns)
    res = run_capture(store, robot, SerialTrigger(port, out), load_model("panda"), CaptureOptions(5), out)
    store.close()
    assert (res.captured, res.discarded, res.complete) == (3, 1, False)
    assert "ignored unknown line 'HELLO'" in out.getvalue()
    s = load_session(tmp_path / "s")
    assert list(s.point) == ["P1", "P1"]


def _device(replies):
    """A TCP 'serial device' on 127.0.0.1 that answers each received line with the next reply, or streams
    them."""
    srv = socket.create_server(("127.0.0.1", 0))
    srv.settimeout(10)

    def run():
        conn, _ = srv.accept()
        time.sleep(0.2)  # pyserial flushes a socket's input when it opens it
        with conn:
            for reply in replies:
                if reply.startswith(b"?"):  # answer a query
                    conn.recv(64)
                    reply = reply[1:]
                conn.sendall(reply)
            time.sleep(1.0)
        srv.close()

    threading.Thread(target=run, daemon=True).start()
    return f"socket://127.0.0.1:{srv.getsockname()[1]}"


def test_serial_trigger_from_a_url_and_bad_urls():
    url = _device([b"CAPTURE\n"])
    trig = SerialTrigger.from_url(url)
    assert trig.wait() == "capture"
    trig.close()
    with pytest.raises(DeviceError, match="cannot open"):
        SerialTrigger.from_url("socket://127.0.0.1:1")


def test_rangefinder_answers_queries_and_reads_streams_from_a_whole_line():
    rf = SerialRangefinder.from_url(_device([b"?D=412.5mm\r\n", b"?0.3071 m\n"]), query=b"D\n")
    assert rf.measure() == 412.5
    assert rf.measure() == pytest.approx(307.1)
    rf.close()
    port = serial.serial_for_url("loop://", timeout=0.05)
    port.write(b"99.0\n")  # an old reading, from another pose: flushed
    real_reset = port.reset_input_buffer
    port.reset_input_buffer = lambda: (
        real_reset(),
        port.write(b"5 mm\n230.25 mm\n"),
    )  # the stream resumes mid-line
    assert SerialRangefinder(port).measure() == 230.25
    with pytest.raises(DeviceError, match="no reading"):
        SerialRangefinder(serial.serial_for_url("loop://", timeout=0.05), query=b"D\n", timeout=0.3).measure()


@pytest.mark.parametrize(
    "line, mm",
    [
        (b"412.5", 412.5),
        (b"D=412.5mm", 412.5),
        (b"41.25 cm\r\n", 412.5),
        (b"0.4125m", 412.5),
        (b"dist: .5 m", 500.0),
        (b"ERR", None),
    ],
)
def test_rangefinder_line_parsing(line, mm):
    assert parse_reading(line) == mm


def test_enter_trigger_keys_and_eof():
    keys = iter(["", "c", "d", "Q", "what"])

    def read_line():  # like input(): EOFError at the end
        try:
            return next(keys)
        except StopIteration:
            raise EOFError from None

    out = io.StringIO()
    trig = EnterTrigger(read_line, out)
    assert [trig.wait() for _ in range(4)] == ["capture", "capture", "discard", "quit"]
    with pytest.raises(InputEnded, match="standard input ended"):  # 'what' is explained, then the EOF:
        trig.wait()  # no operator quit, a stop the command reports (issue 47, item 8)
    assert "'what'" in out.getvalue()


def test_pilot_buttons_map_check_cross_circle():
    class Event:
        def __init__(self, button, pressed):
            self.button, self.pressed = type("B", (), {"value": button}), pressed

    class Desk:
        batches = [
            [Event("check", True), Event("check", False)],
            [Event("up", True)],
            [Event("cross", True)],
            [Event("circle", True)],
        ]

        def poll_buttons(self, timeout):
            return self.batches.pop(0)

    trig = PilotTrigger(FrankyPilot(Desk()))
    assert [trig.wait(), trig.wait(), trig.wait()] == ["capture", "discard", "quit"]


def test_make_trigger_refuses_what_the_backend_cannot_do():
    robot = _fake_robot(1)
    with pytest.raises(DeviceError, match="no pilot buttons"):
        make_trigger("pilot", robot)
    with pytest.raises(DeviceError, match="unknown trigger"):
        make_trigger("pedal", robot)
    with pytest.raises(DeviceError, match="cannot open"):
        make_trigger("serial:/dev/does-not-exist", robot)
