"""Issue 41 item 3: the exposure set at a session's start (``collector.sessions.exposure``) on the fake
cameras, each set to clip: the spot's centre error against the simulated truth with and without it.

* validate's camera (``FakeCamera``, a known view, 0.2 mm/px): a bright pointer, its spot's peak
  ``PEAK`` times full scale over paper at 0.65;
* capture's camera (``SheetCamera``, the A4 sheet through its markers, 0.33 mm/px): the exposure raised
  ``SHEET_GAIN`` times, the paper near clipping as an auto exposure metering on it leaves it.

Prints, per camera: the exposure settled on, clipped px before and after, RMS and max centre error (px),
over ``N`` photos. Run: python benchmarks/bench_exposure.py
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path

import numpy as np

from lasercal.collector.sessions.exposure import clipped_px, readable_by, settle_exposure
from lasercal.collector.sessions.validate import measure_known_view
from lasercal.collector.worlds.cameras import FakeCamera, SpotLook, fake_view

N = 40
PEAK = 6.0
SHEET_GAIN = 2.0


class Beam:
    """A fake robot's true spot: random points within 10 mm of (450, 0), the next on each photo."""

    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)
        self.spot = np.zeros(3)

    def true_spot(self, z: float):
        self.spot = np.r_[450.0 + self.rng.uniform(-10, 10), self.rng.uniform(-10, 10), z]
        return self.spot, 0.0


def validate_camera(control: bool, seed: int = 1, n: int = N):
    """Centre errors (px) of n photos of validate's fake camera, settled first or not; the exposure and
    the clipped px of the first and last photos."""
    view = fake_view((450.0, 0.0), 0.0, (800, 600), 0.2)
    beam = Beam(seed)
    cam = FakeCamera(beam, view, 0.0, seed=seed, look=SpotLook(peak=PEAK), exposure=1.0)
    first = settle_exposure(cam, out=io.StringIO()) if control else cam.photo()
    errs, clip = [], [clipped_px(first)]
    for k in range(n):
        img = first if k == 0 else cam.photo()
        xy, _ = measure_known_view(img, "bench", view)
        errs.append(np.hypot(*(xy - beam.spot[:2])) / 0.2)
    clip.append(clipped_px(img))
    return np.array(errs), cam.exposure, clip


def sheet_camera(control: bool, seed: int = 3, n: int = N):
    """As :func:`validate_camera` for capture's camera on an A4 sheet (markers), spots beside its crosses."""
    from lasercal.collector.hardware import make_robot
    from lasercal.collector.sessions.spotcam import BESIDE_MM, capture_camera
    from lasercal.collector.worlds.fakeworld import World, table_points
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout
    from lasercal.vision.errors import VisionError
    from lasercal.vision.sheet import design_sheet, write_layout

    path = Path(tempfile.mkdtemp()) / "layout.yaml"
    write_layout(path, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 0.0, "yaw_deg": 0.0})
    layout, world = load_layout(path), World()
    cfg = {"backend": "fake", "truth": "panda_thesis_identified", "aim_noise": 3.0, "seed": seed}
    points = table_points(layout, world, BESIDE_MM)
    robot = make_robot(cfg, load_model("panda"), layout.in_base(), 3, points=points)
    cam, measure = capture_camera("fake", cfg, robot, layout, path, world)
    cam.exposure = SHEET_GAIN
    robot.connect()
    errs, clip, names = [], [], list(layout.calibration)
    for k in range(n):
        robot.prompt_point(names[k % len(names)], None, k)
        robot.clock.sleep(10.0)
        if k == 0:
            img = settle_exposure(cam, readable_by(measure), io.StringIO()) if control else cam.photo()
            clip.append(clipped_px(img))
        else:
            img = cam.photo()
        true = layout.sheet.from_base(robot.true_spot(layout.plane_z)[0][None])[0]
        try:
            m = measure(img, f"bench-{k}")
        except VisionError:
            continue
        errs.append(np.hypot(*(m.xy - true)) / 0.33)
    clip.append(clipped_px(img))
    return np.array(errs), cam.exposure, clip


def main() -> None:
    for what, run in (("validate FakeCamera", validate_camera), ("capture SheetCamera", sheet_camera)):
        for control in (False, True):
            e, exposure, clip = run(control)
            on = "on " if control else "off"
            rms = f"{np.sqrt(np.mean(e**2)):.3f} px, max {e.max():.3f} px" if len(e) else "-"
            print(
                f"{what}, exposure control {on}: exposure {exposure:g}, clipped px first/last "
                f"{clip[0]}/{clip[1]}, measured {len(e)}/{N}, centre error RMS {rms}"
            )


if __name__ == "__main__":
    main()
