"""The validation session (``lasercal validate``): the thesis's Section 4.3 check, automated.

A model computes N diverse configurations that it says put the spot on the validation
point; the arm goes to each (moved by backends that can move, otherwise guided by the
operator), a camera photographs the spot, and validation.csv records the measured
configuration and the photo. Where the photo can be mapped to the plane -- the fake
camera's known view, or a layout with fiducial markers -- the spot is measured at once
(``x_mm, y_mm``); otherwise ``lasercal spots`` measures the photos later.

Cameras: an OpenCV capture device (index, URL, or an image sequence such as
``frames/%04d.png``), or ``fake``, which renders the spot the fake robot's true beam
makes, seen from above (``vision.render``).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from lasercal.collector.errors import DeviceError, RobotConnectionError, SessionError
from lasercal.collector.hardware.base import RobotAdapter
from lasercal.collector.sessions.capture import wait_still
from lasercal.collector.sessions.store import CsvLog, write_atomic
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.session import Layout
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.model import RobotModel
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError
from lasercal.vision.render import LaserSpot, Photo, View, look_down, render

VALIDATION_FORMAT = "lasercal-validation/1"


class OpenCVCamera:
    """A camera through ``cv2.VideoCapture``.

    Parameters
    ----------
    device : int or str, device index, stream URL or image-sequence pattern
    flush : int, frames grabbed and dropped before each photo (drivers buffer old frames)
    """

    name = "opencv"

    def __init__(self, device, flush: int = 3):
        self.device, self.flush = device, flush
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

    def close(self) -> None:
        self._cap.release()


def fake_view(centre_xy, plane_z: float, size=(1600, 1200), mm_per_px: float = 0.1) -> View:
    """A camera 800 mm above the table looking straight down at ``centre_xy`` (mm)."""
    return look_down(size=size, mm_per_px=mm_per_px, centre=tuple(centre_xy), height=800.0, z=plane_z)


@dataclass(frozen=True)
class SpotLook:
    """How the fake laser spot looks: Gaussian sigma (px), peak (full scale), speckle contrast."""

    sigma: float = 2.5
    peak: float = 0.8
    speckle: float = 0.2


class FakeCamera:
    """Photos of the spot the fake robot's true beam makes on a blank sheet.

    No reference marks are printed: ink under the spot would bias its centroid, and the
    validation measures the model, not the spot detector.

    Parameters
    ----------
    robot : FakeRobot (anything with ``true_spot(z) -> (spot, length)``)
    view : vision.render.View
    plane_z : float, mm
    seed : int, seed of the image noise
    look : SpotLook
    """

    name = "fake"

    def __init__(self, robot, view: View, plane_z: float, seed: int = 0, look: SpotLook = SpotLook()):
        self.robot, self.view, self.plane_z, self.seed, self.look = robot, view, plane_z, seed, look
        self._count = 0

    def photo(self) -> np.ndarray:
        spot, _ = self.robot.true_spot(self.plane_z)
        u, v = self.view.project(spot[:2])[0]
        self._count += 1
        lk = self.look
        return render(
            Photo(self.view, (), (LaserSpot(u, v, lk.sigma, lk.peak, lk.speckle),)),
            seed=self.seed + self._count,
        )

    def close(self) -> None:
        """Nothing to release."""


def measure_known_view(img: np.ndarray, name: str, view: View) -> np.ndarray:
    """The spot of a photo taken through a known view, on the plane, (2,) mm."""
    spots, _ = detect_spots(img, name)
    return view.unproject(np.array([[spots[0].u, spots[0].v]]))[0]


def measure_with_markers(img: np.ndarray, name: str, markers) -> np.ndarray:
    """The spot of a photo on the plane through the layout's fiducial markers (vision), (2,) mm."""
    from lasercal.vision.measure import measure_photo  # imported here: only layouts with markers need it

    s = measure_photo(img, name, layout=markers).spots[0]
    return np.array([s.x_mm, s.y_mm])


def validation_point(layout: Layout, point: str | None) -> str:
    """The point to validate at: ``point``, or the layout's first validation point."""
    point = point or (layout.validation[0] if layout.validation else None)
    if point is None:
        raise FormatError(
            layout.path, "the layout names no validation point: pass --point", field="validation"
        )
    if point not in layout.points:
        raise FormatError(
            layout.path,
            f"no point {point!r} to validate at (it has {', '.join(layout.points)})",
            field="points",
        )
    return point


@dataclass(frozen=True)
class ValidationResult:
    """Where a validation run wrote its table, and the spots it measured ((k, 2) mm, base frame)."""

    path: Path
    photos: int
    spots: np.ndarray


@dataclass(frozen=True)
class ValidateOptions:
    """How a validation run behaves.

    Attributes
    ----------
    n : int, configurations
    seed : int, seed of the configurations the model computes
    guide : bool, guide the operator even where the backend could move the arm
    speed_threshold, hold, still_timeout, poll : standstill before each photo (rad/s, s, s, s)
    """

    n: int = 60
    seed: int = 0
    guide: bool = False
    speed_threshold: float = 0.005
    hold: float = 0.5
    still_timeout: float = 30.0
    poll: float = 1 / 64


def run_validation(
    folder,
    model: RobotModel,
    model_ref: str,
    layout: Layout,
    point: str,
    robot: RobotAdapter,
    camera,
    opts: ValidateOptions,
    trigger=None,
    measure=None,
    out=sys.stdout,
) -> ValidationResult:
    """Photograph the spot at N configurations ``model`` computes for ``point``; write validation.csv.

    Parameters
    ----------
    folder : path of a new folder: validation.yaml, validation.csv, photos/NNNN.png
    model : RobotModel, the model under test (nominal or identified)
    model_ref : str, how validation.yaml names it
    layout : Layout
    point : str, the validation point's name (see :func:`validation_point`)
    robot : RobotAdapter, connected by this function and closed when it returns
    camera : OpenCVCamera or FakeCamera
    opts : ValidateOptions
    trigger : Trigger, needed when the operator guides the arm
    measure : callable(img, name) -> (2,) mm, or None to leave x_mm, y_mm empty
    out : text stream

    Returns
    -------
    ValidationResult
    """
    p = layout.points[point]
    folder = Path(folder)
    if (folder / "validation.csv").exists():
        raise SessionError(f"{folder} already holds a validation run: choose another folder")
    (folder / "photos").mkdir(parents=True, exist_ok=True)
    planned = aim(model, p, opts.n, np.random.default_rng(opts.seed), **layout.aim_kwargs())
    guided = opts.guide or not robot.can_move
    if guided and trigger is None:
        raise DeviceError(
            f"the {robot.name} backend cannot move the arm: the operator guides it, so a trigger is needed"
        )
    meta = {
        "format": VALIDATION_FORMAT,
        "model": model_ref,
        "point": {"name": point, "xyz": [float(v) for v in p]},
        "plane": {"z": float(layout.plane_z)},
        "n": opts.n,
        "seed": opts.seed,
        "backend": robot.name,
        "camera": camera.name,
        "motion": "guided by the operator" if guided else "moved by the backend",
        "units": {"q": "rad", "x_mm": "mm", "y_mm": "mm", "q_dev": "rad"},
        "columns": {
            "q1..qN": "measured joint positions when the photo was taken",
            "photo": "relative to this folder",
            "x_mm, y_mm": "the spot on the plane, base frame (empty: not measured; use lasercal spots)",
            "q_dev": "largest joint deviation from the configuration the model computed",
        },
    }
    write_atomic(folder / "validation.yaml", yaml.safe_dump(meta, sort_keys=False, width=120))
    header = ["index"] + [f"q{j + 1}" for j in range(model.n)] + ["photo", "x_mm", "y_mm", "q_dev"]
    log = CsvLog(
        folder / "validation.csv",
        header,
        [
            f"lasercal validation of {model_ref} at {point}: q rad, x_mm/y_mm mm "
            f"(plane z = {layout.plane_z:g} mm), q_dev rad; see validation.yaml"
        ],
    )
    w = out.write
    photos, spots = 0, []
    try:
        robot.connect()
        for i, q in enumerate(planned):
            if guided:
                robot.prompt_configuration(q)
                now = robot.read().q
                w(
                    f"\nconfiguration {i + 1}/{opts.n}: guide the arm to q = {np.round(q, 3).tolist()} rad\n"
                    f"  now off by {np.round(q - now, 3).tolist()} rad   [{trigger.hint}]\n"
                )
                cmd = trigger.wait()
                if cmd == "quit":
                    w(f"stopped after {i} photos: {log.path}\n")
                    break
                if cmd == "discard":
                    w(f"configuration {i + 1} skipped\n")
                    continue
            else:
                robot.move_to(q)
            state, peak = wait_still(robot, opts.speed_threshold, opts.hold, opts.still_timeout, opts.poll)
            if state is None:
                w(
                    f"configuration {i + 1}: the arm did not come to rest (max |dq| {peak:.4f} rad/s): "
                    "skipped\n"
                )
                continue
            img = camera.photo()
            name = f"photos/{i:04d}.png"
            if not cv2.imwrite(str(folder / name), img):
                raise DeviceError(f"cannot write {folder / name}")
            row = {
                "index": str(i),
                **{f"q{j + 1}": v for j, v in enumerate(state.q)},
                "photo": name,
                "q_dev": float(np.abs(state.q - q).max()),
            }
            msg = f"photo {i + 1}/{opts.n}: {name}"
            if measure is not None:
                try:
                    xy = measure(img, name)
                except VisionError as e:  # one unreadable photo must not end the run: it stays on disk
                    msg += f", not measured ({e})"
                else:
                    row.update(x_mm=float(xy[0]), y_mm=float(xy[1]))
                    spots.append(xy)
                    msg += f", spot {np.hypot(*(xy - p[:2])):.2f} mm from {point}"
            log.append(row)
            photos += 1
            w(msg + "\n")
    except RobotConnectionError as e:
        raise RobotConnectionError(f"{e}; the photos so far are in {log.path}") from None
    finally:
        log.close()
        robot.close()
        camera.close()
    return ValidationResult(log.path, photos, np.array(spots).reshape(-1, 2))
