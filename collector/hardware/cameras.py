"""Real cameras through OpenCV (``--camera N|URL|frames/%04d.png``), for validation and capture photos."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from lasercal.collector.errors import DeviceError

# CAP_PROP_AUTO_EXPOSURE values that mean manual: V4L2 through OpenCV >= 4.x (1), older builds and
# DirectShow (0.25)
AUTO_OFF = (1.0, 0.25)


def _absent(device) -> bool:
    """A camera that surely is not there: a Linux device index without /dev/videoN, or a frame-file
    pattern (frames/%04d.png) with none of its first files."""
    if isinstance(device, int):
        return sys.platform.startswith("linux") and not Path(f"/dev/video{device}").exists()
    if "%" not in device or "://" in device:
        return False
    try:
        return not any(Path(device % i).exists() for i in range(5))  # OpenCV starts at 0 .. 4
    except (TypeError, ValueError):  # not a printf pattern: let OpenCV judge
        return False


class OpenCVCamera:
    """A camera through ``cv2.VideoCapture``.

    Parameters
    ----------
    device : int or str, device index, stream URL or image-sequence pattern
    flush : int, frames grabbed and dropped before each photo (drivers buffer old frames)
    """

    name = "opencv"
    exposure_control = True  # the tool sets its exposure at a session's start (sessions.exposure)

    def __init__(self, device, flush: int = 3):
        self.device, self.flush = device, flush
        if _absent(device):  # checked here: OpenCV would print lines of its own before failing
            raise DeviceError(
                f"camera: cannot open {device!r}: no such device or frame files (a device index such as 0, a "
                "stream URL, or frames/%04d.png)"
            )
        self._cap = cv2.VideoCapture(device)
        if not self._cap.isOpened():
            raise DeviceError(
                f"camera: cannot open {device!r} (a device index such as 0, a stream URL, or frames/%04d.png)"
            )

    def photo(self) -> np.ndarray:
        """One fresh frame, (h, w, 3) BGR uint8."""
        for _ in range(self.flush):
            self._cap.grab()
        ok, img = self._cap.read()
        if not ok:
            raise DeviceError(f"camera {self.device!r}: no frame")
        return img

    def frame(self) -> np.ndarray:
        """One frame as it comes, no buffered frame dropped (the live view's), (h, w, 3) BGR uint8."""
        ok, img = self._cap.read()
        if not ok:
            raise DeviceError(f"camera {self.device!r}: no frame")
        return img

    def get(self, prop) -> float:
        """An OpenCV property's value (``cv2.CAP_PROP_*``; 0 when the device has none)."""
        return float(self._cap.get(prop))

    def set(self, prop, value) -> bool:
        """Ask for an OpenCV property's value; False when the device refuses (it may also ignore it)."""
        return bool(self._cap.set(prop, value))

    def close(self) -> None:
        self._cap.release()
