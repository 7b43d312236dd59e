"""Issue 46: a calibration rehearsed in a MuJoCo world lasercal did not draw, through the command line only.

    python benchmarks/bench_mujoco.py [DIR] [--seed S] [--per-point N] [--scene-option ...]

``lasercal sheet --place 450 0 0``, ``lasercal mujoco-scene`` (franky-sim's FR3 perturbed with the seed,
the sheet's PDF as texture), ``capture --backend mujoco --camera mujoco --guide move --auto`` (hands-free,
timed), ``solve --extend auto``, ``validate --backend mujoco -n 30 --point P6`` of the nominal (with the
calibration's sheet) and of the calibrated model. Prints the error means validate prints, the session's
wall time, and the vision's error: each measured spot (captures.csv) against where MuJoCo's ray meets the
sheet body at that capture's joint angles (the arm settled there again; the print's scale from
scene.yaml), mm RMS per axis. Extra arguments after ``--scene`` go to ``mujoco-scene`` (``--spring 2:1e-4``).
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")


def lasercal(*args, log=None) -> str:
    t = time.time()
    p = subprocess.run(
        [sys.executable, "-m", "lasercal.collector.cli.main", *map(str, args)], capture_output=True, text=True
    )
    if log is not None:
        Path(log).write_text(p.stdout + p.stderr)
    if p.returncode not in (0, 1):
        raise SystemExit(f"lasercal {' '.join(map(str, args))} failed:\n{p.stderr}")
    print(f"  ({time.time() - t:.0f} s) lasercal {args[0]}", flush=True)
    return p.stdout


def vision_error(session: Path, world_file: Path) -> np.ndarray:
    """Measured spot minus MuJoCo's ray hit on the printed sheet (k, 2) mm, at each measured capture."""
    import yaml

    from lasercal.collector.worlds.mujoco import MujocoWorld

    scale = np.array(yaml.safe_load((world_file.parent / "scene.yaml").read_text())["sheet"]["print_scale"])
    world = MujocoWorld(world_file)
    out = []
    with open(session / "captures.csv") as f:
        for row in csv.DictReader(f):
            if not row["camera_x"]:
                continue
            q = np.array([float(row[f"q{j}"]) for j in range(1, 8)])
            world.command(q)
            world.step(world._path[1] + 1.5)
            hit = world.ray()[0]
            out.append(
                np.array([float(row["camera_x"]), float(row["camera_y"])]) - world.on_sheet(hit)[:2] / scale
            )
    return np.array(out)


def true_error(val: Path, world_file: Path, layout: Path, point: str = "P6") -> float:
    """The validated model's true error at ``point``, mm: each configuration of validation.csv replayed in
    MuJoCo, the ray's hit on the paper (printed mm) against the point's printed place, the mean |error|."""
    import yaml

    from lasercal.collector.worlds.mujoco import MujocoWorld

    scale = np.array(yaml.safe_load((world_file.parent / "scene.yaml").read_text())["sheet"]["print_scale"])
    at = np.array(yaml.safe_load(layout.read_text())["points"][point][:2], dtype=float)
    world, err = MujocoWorld(world_file), []
    with open(val / "validation.csv") as f:
        for row in csv.DictReader(x for x in f if not x.startswith("#")):
            world.command(np.array([float(row[f"q{j}"]) for j in range(1, 8)]))
            world.step(world._path[1] + 1.5)
            err.append(np.linalg.norm(world.on_sheet(world.ray()[0])[:2] / scale - at))
    return float(np.mean(err))


def error_mean(text: str) -> float:
    """validate's 'error mean' (NaN when it measured fewer than two spots)."""
    return float(text.split("error mean ")[1].split(" mm")[0]) if "error mean " in text else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("dir", nargs="?", default="bench_mujoco")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--per-point", type=int, default=9)
    ap.add_argument(
        "--eye", type=float, metavar="MM", help="by eye instead: no camera, this aiming noise (mm)"
    )
    ap.add_argument("--scene", nargs=argparse.REMAINDER, default=[])
    a = ap.parse_args()
    d = Path(a.dir)
    d.mkdir(exist_ok=True)
    for old in ("session", "val_nominal", "val_calibrated", "model.yaml"):  # a rerun starts afresh
        shutil.rmtree(d / old, ignore_errors=True) if (d / old).is_dir() else (d / old).unlink(
            missing_ok=True
        )
    if not (d / "sheet").exists():
        lasercal("sheet", "-o", d / "sheet", "--robot", "fr3", "--place", 450, 0, 0)
    layout = d / "sheet" / "layout.yaml"
    lasercal("mujoco-scene", "--layout", layout, "-o", d / "scene", "--seed", a.seed, "--force", *a.scene)
    world = d / "scene" / "scene.xml"
    common = ["--backend", "mujoco", "--world", world, "--robot", "fr3"]
    t = time.time()
    how = ["--camera", "mujoco", "--guide", "move"] if a.eye is None else ["--aim-noise", a.eye]
    out = lasercal(
        "capture", *common, "--layout", layout, *how, "--auto", "--per-point", a.per_point,
        "-o", d / "session", log=d / "capture.log",
    )  # fmt: skip
    wall = time.time() - t
    measured = sum(1 for r in csv.DictReader(open(d / "session" / "captures.csv")) if r.get("camera_x"))
    rows = sum(1 for _ in csv.DictReader(open(d / "session" / "captures.csv")))
    print(
        f"capture: {rows} captures ({measured} measured by the camera) in {wall:.0f} s wall; "
        f"{out.strip().splitlines()[-1]}"
    )
    solve = lasercal("solve", d / "session", "-o", d / "model.yaml", "--extend", "auto", log=d / "solve.log")
    for line in solve.splitlines():
        if line.startswith(("finding", "noise by kind", "held-out", "fit residual")) or "gain" in line:
            print("  solve:", line.strip())
    nom = lasercal(
        "validate", "fr3", "--sheet-from", d / "model.yaml", "--layout", layout, "--point", "P6", "-n", 30,
        *common, "-o", d / "val_nominal", log=d / "val_nominal.log",
    )  # fmt: skip
    cal = lasercal(
        "validate", d / "model.yaml", "--layout", layout, "--point", "P6", "-n", 30, *common,
        "-o", d / "val_calibrated", log=d / "val_calibrated.log",
    )  # fmt: skip
    print(
        f"validate -n 30 at P6: error mean nominal {error_mean(nom):.3f} mm, calibrated "
        f"{error_mean(cal):.3f} mm"
    )
    promise = [x for x in open(d / "capture.log") if "predicted error at" in x][-1].strip()
    print(f"the coach's last promise: {promise}")
    true = true_error(d / "val_calibrated", world, layout)
    print(f"true error at P6 (validate's configurations replayed, the ray's hit): {true:.3f} mm")
    if a.eye is not None:
        return
    e = vision_error(d / "session", world)
    print(
        f"vision: {len(e)} measured spots against MuJoCo's ray hit: RMS {np.sqrt((e**2).mean(0))[0]:.4f}, "
        f"{np.sqrt((e**2).mean(0))[1]:.4f} mm (x, y), max {np.abs(e).max():.4f} mm"
    )


if __name__ == "__main__":
    main()
