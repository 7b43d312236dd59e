"""Optional laser rangefinder: the measured laser length of each capture (mm).

Serial devices: every reading is a line holding one distance, e.g. ``412.5``,
``D=412.5mm``, ``0.4125 m``: the first number, in mm unless ``cm`` or ``m`` follows it.
Devices that answer a query are sent ``query`` (e.g. ``D\\n``) and the next line is the
reading; devices that stream readings have their input flushed and one line skipped
(it may be cut), then the next line is the reading. Mount the device so that its zero
is the laser aperture, or log its offset: the value is stored as read.
"""

from __future__ import annotations

import re
import time

import numpy as np

from lasercal.collector.errors import DeviceError
from lasercal.collector.hardware.triggers import open_serial

_READING = re.compile(rb"([-+]?\d+(?:\.\d*)?|[-+]?\.\d+)\s*(mm|cm|m)?", re.IGNORECASE)
_SCALE = {b"mm": 1.0, b"cm": 10.0, b"m": 1000.0}


def parse_reading(line: bytes) -> float | None:
    """The distance in a device line, mm; None when the line holds no number."""
    m = _READING.search(line)
    if m is None:
        return None
    return float(m.group(1)) * _SCALE[(m.group(2) or b"mm").lower()]


class SerialRangefinder:
    """A rangefinder on a pyserial port.

    Parameters
    ----------
    port : an open pyserial port with a read timeout
    query : bytes sent before each reading (empty for streaming devices)
    timeout : float, give up after this many seconds, s
    """

    def __init__(self, port, query: bytes = b"", timeout: float = 2.0):
        self.port, self.query, self.timeout = port, query, timeout

    @classmethod
    def from_url(cls, url: str, query: bytes = b"", baudrate: int = 9600) -> SerialRangefinder:
        return cls(open_serial(url, baudrate, "rangefinder"), query)

    def measure(self) -> float:
        """One fresh reading, mm.

        Raises
        ------
        DeviceError
            No reading within the timeout, or the device went away.
        """
        try:
            self.port.reset_input_buffer()  # older readings belong to another pose
            if self.query:
                self.port.write(self.query)
            else:
                self.port.readline()  # a streaming device's first line may be cut
            end = time.monotonic() + self.timeout
            while time.monotonic() < end:
                value = parse_reading(self.port.readline())
                if value is not None:
                    return value
        except Exception as e:  # SerialException / OSError: the device went away
            raise DeviceError(f"rangefinder: device lost ({e})") from None
        raise DeviceError(f"rangefinder: no reading within {self.timeout} s")

    def close(self) -> None:
        self.port.close()


class FakeRangefinder:
    """The fake robot's true laser length plus Gaussian noise (std ``noise`` mm)."""

    def __init__(self, robot, plane_z: float, noise: float = 0.5, seed: int = 0):
        self.robot, self.plane_z, self.noise = robot, plane_z, noise
        self._rng = np.random.default_rng([seed, 0x4A9E])

    def measure(self) -> float:
        return self.robot.true_spot(self.plane_z)[1] + self._rng.normal(0.0, self.noise)

    def close(self) -> None:
        """Nothing to release."""
