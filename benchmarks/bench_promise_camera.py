"""Issue 38: the coach's promise on camera sessions, through the public command line, on many seeds.

Per seed: ``lasercal sheet --place 450 0 0``, ``capture --backend fake --auto --per-point 9 --aim-noise 3
--camera fake --seed S`` (every effect of the simulated world on, the coach planning each spot anywhere on
the sheet), the coach's last promise read off the screen ("predicted error at P6, P7: E ± U mm", the RMS
in-plane spot error it expects of ``solve``'s model where the robot is used), ``solve --extend auto
--folds 0``, then the error that model truly makes there: the RMS, over 60 configurations of the true
robot aiming at P6 and P7, of the distance between where the model says the beam meets the sheet (its
sheet pose, print scale and tilt) and where it truly does (the printed sheet's coordinates, as the camera
reads them), noise-free.

    python benchmarks/bench_promise_camera.py [SEEDS [FIRST]]     (default 20 from 0; ~1.5 min a seed)

Prints a line per seed and the ratio's median and worst.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.sheet import SheetPose


def lasercal(*args, cwd) -> str:
    return subprocess.run(["lasercal", *args], cwd=cwd, capture_output=True, text=True, check=True).stdout


def on_sheet(model, q: np.ndarray) -> np.ndarray:
    """Where ``model``'s beams meet its sheet (eq. S3: the plane's height where the spot is), sheet mm."""
    z = np.full(len(q), model.plane_z)
    for _ in range(3):  # the height under the spot, the spot at that height: converged to 1e-9 mm
        xy = model.sheet.from_base(predict_spots(model, q, z)[0])
        z = model.sheet.to_base(xy, model.plane_z)[:, 2]
    return xy


def true_error(where: Path, seed: int) -> float:
    """RMS distance (mm) between the model's and the truth's spots on the printed sheet at P6 and P7."""
    session = load_session(where / "s")
    world = session.meta["simulated"]["world"]
    truth = load_model("panda_thesis_identified")
    printed = SheetPose(450.0, 0.0, 0.0, *world["print_scale"])
    z = -8.0 + world["sheet_dz_mm"]
    layout = load_layout(where / "sheet" / "layout.yaml")
    rng = np.random.default_rng([seed, 61])
    q = np.concatenate(
        [
            aim(truth, printed.to_base(layout.points[p][None], z)[0], 30, rng, **layout.aim_kwargs())
            for p in ("P6", "P7")
        ]
    )
    xy_true = printed.from_base(predict_spots(truth, q, z)[0])
    model = load_model(where / "m.yaml")
    return float(np.sqrt(np.mean(np.sum((on_sheet(model, q) - xy_true) ** 2, axis=1))))


def main(seeds: int = 20, first: int = 0) -> None:
    rows = []
    for seed in range(first, first + seeds):
        with tempfile.TemporaryDirectory() as d:
            where = Path(d)
            lasercal("sheet", "-o", "sheet", "--place", "450", "0", "0", cwd=where)
            cap = [
                "capture",
                "--layout",
                "sheet/layout.yaml",
                "--robot",
                "panda",
                "--backend",
                "fake",
                "--auto",
            ]
            cap += [
                "--per-point",
                "9",
                "--aim-noise",
                "3",
                "--camera",
                "fake",
                "--seed",
                str(seed),
                "-o",
                "s",
            ]
            said = lasercal(*cap, cwd=where)
            promise = float(re.findall(r"predicted error at P6, P7: ([0-9.]+)", said)[-1])
            lasercal("solve", "s", "-o", "m.yaml", "--extend", "auto", "--folds", "0", cwd=where)
            err = true_error(where, seed)
        rows.append((promise, err))
        print(
            f"seed {seed:2d}: promise {promise:.3f} mm, solve's model {err:.4f} mm ({err / promise:.2f}x)",
            flush=True,
        )
    promise, err = np.array(rows).T
    r = err / promise
    print(
        f"\n{seeds} seeds: measured / promise median {np.median(r):.2f}, worst {r.max():.2f} (seed "
        f"{first + int(np.argmax(r))}); over 1.6x: {int(np.sum(r > 1.6))} of {seeds}"
    )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
