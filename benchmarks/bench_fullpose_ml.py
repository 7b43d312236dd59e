"""Full pose from circle points: maximum likelihood (default) vs the paper's circle method vs the CRB.

Run from the repository: ``python benchmarks/bench_fullpose_ml.py [seeds]``. Simulated circle-point
sessions of a Panda (nominal ``panda``, truth ``panda_thesis_identified``), the sensor frame 2.51 m
from the base and rotated (x-y-z Euler 20, -30, 135 deg), g = 30 configurations x m = 6 angles in
+20 deg steps, target 50 mm off the last axis; base and tool estimated first (``--estimate-frames``).
Per noise level and seed: the held-out position and rotation errors of {E} against the truth on 200
fresh configurations, and the Cramer-Rao prediction (:func:`solver.identify.fullpose_ml.frame_crb`,
from the Jacobian at the truth) for the same configurations. Printed: RMS over seeds and held-out
configurations (the CRB as the root of the mean predicted squared error), and the ratios.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.solver.analysis.simulate import random_configs
from lasercal.solver.formats.robots import load_model
from lasercal.solver.identify.fullpose import default_target, simulate_circlepoint
from lasercal.solver.identify.fullpose_ml import (
    TARGET,
    calibrate_points,
    frame_crb,
    frame_error_norms,
    frame_model,
)
from lasercal.solver.kinematics.poe import fk

SENSOR = np.eye(4)
SENSOR[:3, :3] = Rotation.from_euler("xyz", [20, -30, 135], degrees=True).as_matrix()
SENSOR[:3, 3] = [1800.0, -1500.0, 900.0]


def sweep(noise: float, seeds: int, g: int = 30, m: int = 6) -> dict:
    """Mean squared held-out errors (pos mm^2, rot rad^2) of ml, circle and the CRB over seeds."""
    nom, tru = load_model("panda"), load_model("panda_thesis_identified")
    tgt = default_target(tru)
    truth = tru.replace(sensor_pose=SENSOR, targets={TARGET: tgt})
    E = frame_model(truth)
    out = {k: [] for k in ("ml", "circle", "crb")}
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        d = simulate_circlepoint(tru, g, m, np.radians(20), noise, rng, tgt, SENSOR)
        qe = random_configs(tru, 200, rng)
        TE = fk(E.screws, E.ee_pose, qe)
        cal = calibrate_points(nom, d, estimate=True)
        for key, model in (("ml", cal.model), ("circle", cal.circle.model)):
            dp, dr = frame_error_norms(fk(model.screws, model.ee_pose, qe), TE)
            out[key].append([np.mean(dp**2), np.mean(dr**2)])
        out["crb"].append(np.square(frame_crb(truth, d.q.reshape(-1, tru.n), noise, qe)))
    out = {k: np.array(v) for k, v in out.items()}
    rms = {k: np.sqrt(v.mean(axis=0)) for k, v in out.items()}
    # 95 % interval of ML/CRB from the seed-to-seed scatter of the squared errors (delta method)
    rel = 1.96 * out["ml"].std(axis=0, ddof=1) / np.sqrt(seeds) / out["ml"].mean(axis=0) / 2
    rms["ci"] = rel
    return rms


def main(seeds: int = 200) -> None:
    print(
        "== {E} from circle points, Panda, sensor 2.51 m away and rotated, g = 30 x m = 6 (+20 deg); "
        f"held-out RMS over {seeds} seeds x 200 configurations"
    )
    print(
        f"{'noise mm':>8} | {'CRB pos mm':>10} {'ML':>9} {'ML/CRB':>11} {'circle':>9} {'circ/CRB':>8} | "
        f"{'CRB rot mrad':>12} {'ML':>8} {'ML/CRB':>11} {'circle':>8} {'circ/CRB':>8} | s"
    )
    print("   (ML/CRB +- its 95 % interval over the seeds; the same seeds at both noise levels)")
    for noise in (0.01, 0.05):
        t0 = time.perf_counter()
        r = sweep(noise, seeds)
        c, ml, ci = r["crb"], r["ml"], r["circle"]
        ratio, pm = ml / c, ml / c * r["ci"]
        pos = f"{c[0]:10.5f} {ml[0]:9.5f} {ratio[0]:5.3f}+-{pm[0]:.3f} {ci[0]:9.5f} {ci[0] / c[0]:8.2f}"
        c, ml, ci = c * 1e3, ml * 1e3, ci * 1e3  # rotations in mrad
        rot = f"{c[1]:12.5f} {ml[1]:8.5f} {ratio[1]:5.3f}+-{pm[1]:.3f} {ci[1]:8.5f} {ci[1] / c[1]:8.2f}"
        print(f"{noise:8.2f} | {pos} | {rot} | {time.perf_counter() - t0:.0f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)
