"""What tells a session to capture: the Enter key, a serial button box or foot pedal, the
robot's pilot buttons, or the simulated operator.

Every trigger answers :meth:`Trigger.wait` with one command: ``capture``, ``discard``
(remove the last capture) or ``quit`` (stop; the session can be resumed).

Serial protocol (device -> computer, one command per line, ASCII, case-insensitive,
``\\n`` or ``\\r\\n``): ``CAPTURE``, ``DISCARD``, ``QUIT``. Other lines are ignored with a
warning. Commands are queued in order, so a double press captures twice. Any baud rate;
the port is a pyserial URL (``/dev/ttyUSB0``, ``socket://HOST:PORT``, ``loop://``).
"""

from __future__ import annotations

import sys
import time

from lasercal.collector.errors import DeviceError, InputEnded
from lasercal.collector.hardware.base import PilotButtons, import_extra

COMMANDS = ("capture", "discard", "quit")


class Trigger:
    """Base class: ``hint`` says on screen how to trigger; ``wait`` blocks until a command."""

    hint = ""

    def wait(self) -> str:
        raise NotImplementedError

    def close(self) -> None:
        """Release the device."""


class EnterTrigger(Trigger):
    """The keyboard: Enter captures, ``d`` Enter discards the last capture, ``q`` Enter quits.

    Parameters
    ----------
    read_line : callable() -> str, e.g. ``input`` (its EOF raises :class:`InputEnded`: a script's or a
        closed terminal's end is no operator's quit)
    out : text stream for the hint after an unknown answer
    """

    hint = "Enter: capture · d Enter: discard the last capture · q Enter: quit"
    KEYS = {"": "capture", "c": "capture", "d": "discard", "q": "quit"}

    def __init__(self, read_line=input, out=sys.stdout):
        self.read_line, self.out = read_line, out

    def wait(self) -> str:
        while True:
            try:
                line = self.read_line()
            except EOFError:
                raise InputEnded(
                    "standard input ended: nothing can press Enter to trigger (run it at a terminal, or "
                    "trigger with --trigger serial:URL or pilot; --auto: the simulated operator of --backend "
                    "fake)"
                ) from None
            key = line.strip().lower()[:1]
            if key in self.KEYS:
                return self.KEYS[key]
            self.out.write(f"  ? {line.strip()!r}: {self.hint}\n")


def open_serial(url: str, baudrate: int, what: str):
    """A pyserial port at a URL (``/dev/ttyUSB0``, ``socket://...``, ``loop://``), 0.2 s read timeout."""
    serial = import_extra("serial", f"the {what}", "pyserial")
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=0.2)
    except (serial.SerialException, ValueError) as e:
        raise DeviceError(f"{what}: cannot open {url}: {e}") from None


class SerialTrigger(Trigger):
    """A button box or foot pedal speaking the serial protocol of this module.

    Parameters
    ----------
    port : an open pyserial port (``serial_for_url`` with a read timeout)
    out : text stream for warnings about unknown lines
    """

    hint = "pedal / button box: CAPTURE, DISCARD, QUIT"

    def __init__(self, port, out=sys.stdout):
        self.port, self.out = port, out

    @classmethod
    def from_url(cls, url: str, baudrate: int = 9600, out=sys.stdout) -> SerialTrigger:
        """Open the device at a pyserial URL."""
        return cls(open_serial(url, baudrate, "serial trigger"), out)

    def wait(self) -> str:
        while True:
            try:
                raw = self.port.readline()
            except Exception as e:  # pyserial raises SerialException or OSError when the device goes away
                raise DeviceError(f"serial trigger: device lost ({e})") from None
            if not raw:
                continue  # read timeout: keep waiting
            cmd = raw.decode("ascii", "replace").strip().lower()
            if cmd in COMMANDS:
                return cmd
            if cmd:
                self.out.write(
                    f"  serial trigger: ignored unknown line {cmd.upper()!r} (expected CAPTURE, DISCARD or "
                    "QUIT)\n"
                )

    def close(self) -> None:
        self.port.close()


class PilotTrigger(Trigger):
    """The robot's pilot buttons: check captures, cross discards, circle quits."""

    hint = "pilot buttons: ✓ capture · ✗ discard the last capture · ○ quit"

    def __init__(self, buttons: PilotButtons):
        self.buttons = buttons

    def wait(self) -> str:
        while True:
            events = self.buttons.poll(0.5)
            if events:
                return events[0]

    def close(self) -> None:
        self.buttons.close()


class AutoTrigger(Trigger):
    """The simulated operator: captures as soon as asked, after ``pace`` real seconds (to watch it)."""

    hint = "automatic (simulated operator)"

    def __init__(self, pace: float = 0.0):
        self.pace = pace

    def wait(self) -> str:
        if self.pace > 0:
            time.sleep(self.pace)
        return "capture"


def make_trigger(spec: str, adapter, read_line=input, out=sys.stdout) -> Trigger:
    """A trigger from its command-line form: ``enter``, ``serial:URL`` or ``pilot``."""
    if spec == "enter":
        return EnterTrigger(read_line, out)
    if spec.startswith("serial:"):
        return SerialTrigger.from_url(spec[len("serial:") :], out=out)
    if spec == "pilot":
        buttons = adapter.pilot_buttons()
        if buttons is None:
            raise DeviceError(
                f"the {adapter.name} backend offers no pilot buttons: use --trigger enter or serial:URL"
            )
        return PilotTrigger(buttons)
    raise DeviceError(f"unknown trigger {spec!r}: use enter, serial:URL or pilot")
