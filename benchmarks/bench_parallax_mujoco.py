"""Eq. S8 against MuJoCo's photos of a curled sheet: how much of the camera's error on raised paper it
explains.

    python benchmarks/bench_parallax_mujoco.py [--curl MM] [--draws N] [--photos K]

``lasercal sheet --place 450 0 0`` and ``mujoco-scene --exact --curl MM`` (the paper a mesh, eq. M1; the arm,
laser and print exact). Each draw aims the arm at K random points inside the markers (the nominal FR3, the
draw's seed), renders MuJoCo's photo, measures its spot as a capture does (``measure_spot``: the spot and
where the markers put the camera, eq. V2) and scores it against where MuJoCo's ray meets the paper (the
truth, printed mm): RMS per axis of the error as measured, and after eq. S8 with M1's curl (kxx =
2 curl / half height^2) from the eye the photo's markers gave. Prints each draw's ratio (after / before,
both axes together), then their spread: tests/test_mujoco.py bounds one draw by the largest of them.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

os.environ.setdefault("MUJOCO_GL", "egl")


def lasercal(*args) -> None:
    p = subprocess.run(
        [sys.executable, "-m", "lasercal.collector.cli.main", *map(str, args)], capture_output=True
    )
    if p.returncode:
        raise SystemExit(p.stderr.decode())


def curled_scene(folder: Path, curl: float) -> Path:
    """A printed sheet at 450 0 0 and its exact MuJoCo scene curled by ``curl`` mm: the scene's folder."""
    lasercal("sheet", "-o", folder / "sheet", "--robot", "fr3", "--place", 450, 0, 0)
    lasercal("mujoco-scene", "--layout", folder / "sheet" / "layout.yaml", "-o", folder / "scene", "--exact",
             "--curl", curl)  # fmt: skip
    return folder / "scene"


def seen_and_true(scene: Path, layout_file: Path, curl: float, n: int, seed: int) -> np.ndarray:
    """(k, 3, 2): each measured photo's error as measured, after eq. S8, and eq. S8's field, mm (printed)."""
    from lasercal.collector.sessions.spotcam import measure_spot
    from lasercal.collector.worlds.mujoco import MujocoCamera, MujocoWorld
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.kinematics.aim import aim
    from lasercal.solver.kinematics.parallax import parallax_rows
    from lasercal.vision.errors import VisionError
    from lasercal.vision.plane import load_markers

    layout, markers = load_layout(layout_file), load_markers(layout_file)
    corners = np.concatenate([np.asarray(c, dtype=float) for c in markers.corners.values()])
    half = yaml.safe_load(layout_file.read_text())["paper"]["height_mm"] / 2
    k = np.array([2 * curl / half**2, 0.0, 0.0])  # eq. M1 in eq. S6's terms (the print exact)
    world, rng = MujocoWorld(scene / "scene.xml"), np.random.default_rng(seed)
    camera, fr3 = MujocoCamera(world), load_model("fr3")
    camera.exposure = 0.5  # what a capture's exposure settles to here: the spot unclipped
    lo, hi = corners.min(axis=0) + 15, corners.max(axis=0) - 15
    out = []
    for _ in range(n):
        p = layout.sheet.to_base(rng.uniform(lo, hi)[None], layout.plane_z)[0]
        world.d.qpos[world.c.qadr] = aim(fr3, p, 1, rng)[0]
        try:
            got = measure_spot(camera.photo(), "bench", markers)
        except VisionError:  # hidden by the arm, clipped: not measured, as a capture's would not be
            continue
        true = world.on_sheet(camera.last_hit)[:2]
        field = parallax_rows(true[None], got.eye[None], corners)[0] @ k
        out.append([got.xy - true, got.xy - true - field, field])
    camera.close()
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--curl", type=float, default=2.0)
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--photos", type=int, default=6)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = curled_scene(Path(tmp), a.curl)
        ratios, t0 = [], time.time()
        for seed in range(a.draws):
            e = seen_and_true(scene, Path(tmp) / "sheet" / "layout.yaml", a.curl, a.photos, seed)
            rms = np.sqrt(np.mean(e**2, axis=0))  # (3, 2)
            ratios.append(np.linalg.norm(rms[1]) / np.linalg.norm(rms[0]))
            print(
                f"seed {seed}: {len(e)} photos, as measured {rms[0].round(4)} mm RMS (x, y), after eq. S8 "
                f"{rms[1].round(4)}, mean after {e[:, 1].mean(axis=0).round(4)}; ratio {ratios[-1]:.3f}",
                flush=True,
            )
    r = np.array(ratios)
    took = time.time() - t0
    said = f"ratio after / before over {len(r)} draws: median {np.median(r):.3f}, max {r.max():.3f}"
    print(said, f"({took:.0f} s)")


if __name__ == "__main__":
    main()
