"""Issue 51: tests/test_mujoco.py's short MuJoCo session, over several scene seeds, to bound its figures.

    python benchmarks/bench_mujoco_short.py [DIR] [--seeds 1 2 3] [--per-point 3] [-n 4] [--spring 2:1e-4]

Per scene seed: ``mujoco-scene --seed S --spring 2:1e-4`` (the test's world: franky-sim's FR3 perturbed, a
passive spring after joint 2), ``capture --camera mujoco --guide move --auto --per-point N`` (hands-free),
``solve --extend auto --folds 0``, ``validate -n 4 --point P6`` of the nominal (with the calibration's sheet)
and of the calibrated model. Prints, per seed: the captures measured, solve's finding and the fitted
compliance c (rad/Nm, the model file's sign), each validate's exit code, spots measured and error mean; then
the spread over the seeds. Appends one line per seed to DIR/results.txt (a rerun adds seeds).
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

os.environ.setdefault("MUJOCO_GL", "egl")


def lasercal(*args) -> tuple[int, str, str]:
    p = subprocess.run(
        [sys.executable, "-m", "lasercal.collector.cli.main", *map(str, args)], capture_output=True, text=True
    )
    return p.returncode, p.stdout, p.stderr


def error_mean(text: str) -> float:
    return float(text.split("error mean ")[1].split(" mm")[0]) if "error mean " in text else float("nan")


def measured(text: str) -> int:
    return int(text.split(" spots measured")[0].split()[-1]) if " spots measured" in text else -1


def one(d: Path, seed: int, per_point: int, n: int, scene: list[str]) -> str:
    import yaml

    d.mkdir(parents=True, exist_ok=True)
    if not (d.parent / "sheet").exists():
        lasercal("sheet", "-o", d.parent / "sheet", "--robot", "fr3", "--place", 450, 0, 0)
    layout = d.parent / "sheet" / "layout.yaml"
    for old in ("scene", "s", "v0", "v1"):
        shutil.rmtree(d / old, ignore_errors=True)
    t = time.time()
    code, _, err = lasercal("mujoco-scene", "--layout", layout, "-o", d / "scene", "--seed", seed, *scene)
    assert code == 0, err
    world = d / "scene" / "scene.xml"
    common = ["--backend", "mujoco", "--world", world, "--robot", "fr3"]
    code, out, err = lasercal(
        "capture", *common, "--layout", layout, "--camera", "mujoco", "--guide", "move", "--auto",
        "--per-point", per_point, "-o", d / "s",
    )  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader(open(d / "s" / "captures.csv")))
    cam = sum(1 for r in rows if r.get("camera_x"))
    code, sout, err = lasercal("solve", d / "s", "-o", d / "m.yaml", "--folds", 0, "--extend", "auto")
    assert code == 0, err
    (d / "solve.log").write_text(sout)
    finding = next((ln.strip() for ln in sout.splitlines() if ln.strip().startswith("finding")), "?")
    ext = (yaml.safe_load((d / "m.yaml").read_text()) or {}).get("extensions") or {}
    jc = ext.get("joint_compliance")
    c = f"{jc['joints']}:{jc['c']}" if jc else "none"
    res = []
    for model, extra in (("fr3", ["--sheet-from", d / "m.yaml"]), (d / "m.yaml", [])):
        out_dir = d / f"v{len(res)}"
        code, vout, err = lasercal(
            "validate", model, "--layout", layout, "--point", "P6", "-n", n, *common, *extra, "-o", out_dir
        )
        res.append((code, measured(vout), error_mean(vout)))
    line = (
        f"seed {seed} pp {per_point} n {n} scene {' '.join(scene) or '-'}: "
        f"captures {len(rows)} camera {cam}; "
        f"{finding}; c {c}; nominal exit {res[0][0]} spots {res[0][1]} mean {res[0][2]:.4f}; calibrated exit "
        f"{res[1][0]} spots {res[1][1]} mean {res[1][2]:.4f}; {time.time() - t:.0f} s"
    )
    return line


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("dir", nargs="?", default="bench_mujoco_short")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--per-point", type=int, default=3)
    ap.add_argument("-n", type=int, default=4)
    ap.add_argument("--scene", nargs=argparse.REMAINDER, default=["--spring", "2:1e-4"])
    a = ap.parse_args()
    d = Path(a.dir)
    for seed in a.seeds:
        line = one(d / f"seed{seed}", seed, a.per_point, a.n, a.scene)
        print(line, flush=True)
        with open(d / "results.txt", "a") as f:
            f.write(line + "\n")


if __name__ == "__main__":
    main()
