"""Camera model: lens distortion, the camera YAML and ``lasercal camera-calibrate``.

Units: pixels (OpenCV convention, pixel centres at integer coordinates) for image
points, the camera matrix K and the reprojection error; mm for the calibration
pattern's squares. Distortion follows OpenCV's model ``(k1, k2, p1, p2[, k3, ...])``.

Camera YAML (``format: lasercal-camera/1``)::

    format: lasercal-camera/1
    units: {image: px, pattern: mm}
    image_size: [4000, 3000]        # width, height, px
    K: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    dist: [k1, k2, p1, p2, k3]
    rms_px: 0.21                    # RMS reprojection error of the calibration, px
    pattern: {type: chessboard, cols: 9, rows: 6, square: 25.0}
    photos: 12                      # photos used
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from lasercal.vision.errors import CalibrationError, LayoutError

CAMERA_FORMAT = "lasercal-camera/1"
_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)


def distort(uv: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Ideal (undistorted) pixels to the pixels a lens with ``dist`` records.

    Parameters
    ----------
    uv : (n, 2) array, ideal pixel coordinates, px
    K : (3, 3) array, camera matrix
    dist : (k,) array, OpenCV distortion coefficients

    Returns
    -------
    (n, 2) array, distorted pixel coordinates, px
    """
    uv = np.asarray(uv, float).reshape(-1, 2)
    if not np.any(dist):
        return uv.copy()
    xn = (uv - K[:2, 2]) / np.diag(K)[:2]
    rays = np.column_stack([xn, np.ones(len(xn))])
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, np.asarray(dist, float))
    return out.reshape(-1, 2)


def undistort(uv: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Inverse of :func:`distort`: recorded pixels to ideal pixels (same K).

    Parameters
    ----------
    uv : (n, 2) array, recorded pixel coordinates, px
    K : (3, 3) array
    dist : (k,) array

    Returns
    -------
    (n, 2) array, ideal pixel coordinates, px
    """
    uv = np.asarray(uv, float).reshape(-1, 2)
    if not np.any(dist) or len(uv) == 0:
        return uv.copy()
    # The default 5 iterations leave ~0.1 px at the corners of a wide-angle photo.
    out = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, np.asarray(dist, float), P=K, criteria=_CRITERIA)
    return out.reshape(-1, 2)


@dataclass(frozen=True)
class Camera:
    """Intrinsics of one camera.

    Attributes
    ----------
    size : (width, height), px
    K : (3, 3) array, camera matrix, px
    dist : (k,) array, OpenCV distortion coefficients
    rms_px : float, RMS reprojection error of the calibration, px
    """

    size: tuple[int, int]
    K: np.ndarray
    dist: np.ndarray
    rms_px: float = float("nan")

    def undistort(self, uv: np.ndarray) -> np.ndarray:
        """Recorded (n, 2) pixels to ideal pixels, px."""
        return undistort(uv, self.K, self.dist)

    def check_size(self, size: tuple[int, int], image: str) -> None:
        """Raise if a photo's (width, height) differs from the calibrated size."""
        if tuple(size) != tuple(self.size):
            raise CalibrationError(
                f"{image}: image is {size[0]}x{size[1]} px but the camera was calibrated "
                f"at {self.size[0]}x{self.size[1]} px (rotated or resized photo?)"
            )


WHOLE = "# whole file: it ends with the line '...' (a copy cut short lacks it)"
"""The first line of a YAML file lasercal writes, whose last line is ``...``: one that opens with it
and lacks the end was cut short (solver/whole.py keeps the same line; vision stands alone)."""


def whole_yaml(doc, head: str = "", **kw) -> str:
    """``doc`` as the text of a whole YAML file: :data:`WHOLE`, ``head``, the YAML and ``...``."""
    return f"{WHOLE}\n{head}" + yaml.safe_dump(doc, explicit_end=True, **kw)


def read_yaml(path: Path, what: str):
    """Parse a YAML file; unreadable, binary, non-UTF text or invalid files raise LayoutError naming the
    file.

    The bytes go to PyYAML, which decodes UTF-8 and, after a byte-order mark, UTF-16 (a Windows editor's
    'Unicode'); any other encoding is a reader error, named with its position.
    """
    try:
        data = Path(path).read_bytes()
    except IsADirectoryError:
        raise LayoutError(path, f"is a folder (expected a {what})") from None
    except OSError as exc:
        raise LayoutError(path, f"cannot read {what} ({exc.strerror})") from None
    text = data.decode("utf-8", "replace").replace("\r\n", "\n").lstrip("\ufeff")
    lines = [ln.rstrip() for ln in text.split("\n")]
    if WHOLE in lines and [ln for ln in lines if ln][-1] != "...":
        raise LayoutError(
            path,
            f"line {len(text.splitlines())}: cut short: the file ends before its last line '...' "
            f"(a write killed, or a partial copy; expected the whole {what})",
        )
    try:
        return yaml.safe_load(data)
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None) or getattr(exc, "position", None)
        line = f"line {where.line + 1}: " if hasattr(where, "line") else ""
        reason = getattr(exc, "problem", None) or getattr(exc, "reason", None) or exc
        raise LayoutError(path, f"{line}not valid YAML text ({reason}; expected a UTF-8 {what})") from None


def load_camera(path) -> Camera:
    """Read a camera YAML (``format: lasercal-camera/1``).

    Raises
    ------
    LayoutError
        The file is missing or malformed; the message names the file and field.
    """
    path = Path(path)
    doc = read_yaml(path, "camera file")
    if not isinstance(doc, dict) or doc.get("format") != CAMERA_FORMAT:
        raise LayoutError(path, f"expected '{CAMERA_FORMAT}'", "format")
    try:
        size = tuple(int(s) for s in doc["image_size"])
        if len(size) != 2 or min(size) <= 0:
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise LayoutError(path, "expected [width, height] in px", "image_size") from None
    try:
        K = np.array(doc["K"], float)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise LayoutError(path, "expected a 3x3 camera matrix with positive focal lengths", "K") from None
    try:
        dist = np.array(doc.get("dist", []), float).ravel()
        if len(dist) not in (0, 4, 5, 8, 12, 14) or not np.all(np.isfinite(dist)):
            raise ValueError
    except (TypeError, ValueError):
        raise LayoutError(path, "expected 4, 5, 8, 12 or 14 OpenCV distortion coefficients", "dist") from None
    return Camera(size, K, dist, float(doc.get("rms_px", float("nan"))))


def save_camera(path, camera: Camera, pattern: dict, photos: int) -> None:
    """Write a camera YAML (see the module docstring)."""
    doc = {
        "format": CAMERA_FORMAT,
        "units": {"image": "px", "pattern": "mm"},
        "image_size": [int(s) for s in camera.size],
        "K": np.round(camera.K, 6).tolist(),
        "dist": np.round(camera.dist, 8).tolist(),
        "rms_px": round(float(camera.rms_px), 4),
        "pattern": pattern,
        "photos": int(photos),
    }
    Path(path).write_text(whole_yaml(doc, sort_keys=False, default_flow_style=None))


def aruco_dictionary(name: str, path="layout", field="markers.dictionary"):
    """OpenCV's predefined ArUco dictionary called ``name`` (e.g. ``"DICT_4X4_50"``)."""
    if not isinstance(name, str) or not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise LayoutError(path, f"'{name}' is not an OpenCV ArUco dictionary (e.g. DICT_4X4_50)", field)
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def chessboard_points(gray: np.ndarray, cols: int, rows: int, square: float):
    """Inner corners of a chessboard in one photo.

    Parameters
    ----------
    gray : (h, w) uint8 array
    cols, rows : int, inner corners per row and per column
    square : float, side of a square, mm

    Returns
    -------
    (object (n, 3) mm, image (n, 2) px) arrays, or None when the board is not found.
    """
    found, corners = cv2.findChessboardCornersSB(gray, (cols, rows), flags=cv2.CALIB_CB_ACCURACY)
    if not found:
        return None
    obj = np.zeros((rows * cols, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    return obj, corners.reshape(-1, 2)


def charuco_points(gray: np.ndarray, detector) -> tuple[np.ndarray, np.ndarray] | None:
    """ChArUco corners of one photo, as (object (n, 3) mm, image (n, 2) px) arrays.

    Returns None when fewer than 6 corners are found (too few to constrain a view).
    """
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < 6:
        return None
    obj, img = detector.getBoard().matchImagePoints(corners, ids)
    return obj.reshape(-1, 3).astype(np.float32), img.reshape(-1, 2).astype(np.float32)


def calibrate(images: list[tuple[str, np.ndarray]], pattern: dict, warn=print) -> tuple[Camera, int]:
    """Calibrate a camera from photos of a chessboard or a ChArUco board.

    Parameters
    ----------
    images : list of (name, (h, w) uint8 grey array), all of one size
    pattern : dict
        ``{type: chessboard, cols, rows, square}`` or
        ``{type: charuco, cols, rows, square, marker, dictionary}``; cols and rows
        count inner corners (chessboard) or squares (ChArUco); lengths in mm.
    warn : callable taking a message, for photos where the pattern is not found

    Returns
    -------
    camera : Camera, with the RMS reprojection error in px
    used : int, photos in which the pattern was found

    Raises
    ------
    CalibrationError
        Photos of different sizes, or the pattern found in fewer than 3 photos.
    """
    sizes = {img.shape[::-1] for _, img in images}
    if len(sizes) != 1:
        raise CalibrationError(
            "photos have different sizes: " + ", ".join(f"{w}x{h}" for w, h in sorted(sizes))
        )
    if pattern["type"] == "charuco":
        board = cv2.aruco.CharucoBoard(
            (pattern["cols"], pattern["rows"]),
            pattern["square"],
            pattern["marker"],
            aruco_dictionary(pattern["dictionary"]),
        )
        detector = cv2.aruco.CharucoDetector(board)
    obj, img = [], []
    for name, gray in images:
        if pattern["type"] == "charuco":
            found = charuco_points(gray, detector)
        else:
            found = chessboard_points(gray, pattern["cols"], pattern["rows"], pattern["square"])
        if found is None:
            warn(f"{name}: calibration pattern not found, photo skipped")
            continue
        obj.append(found[0])
        img.append(found[1])
    if len(obj) < 3:
        raise CalibrationError(
            f"the calibration pattern was found in {len(obj)} of {len(images)} photos; "
            "at least 3 are needed (from different angles)"
        )
    size = sizes.pop()
    # k3 only helps wide-angle lenses and runs wild when the photos leave the corners empty.
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, size, None, None, flags=cv2.CALIB_FIX_K3)
    return Camera(tuple(int(s) for s in size), K, dist.ravel(), float(rms)), len(obj)
