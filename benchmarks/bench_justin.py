"""DLR's Agile Justin, 350 shared rows: 5-fold cross-validation by record of four models, and the solve time.

    python benchmarks/bench_justin.py [../shared/data/justin/measurements.csv] [--seed 0] [--folds 5] [--auto]
    python benchmarks/bench_justin.py --folds 0     # the solve times only

Solve times: the 700-capture fit of geometry + joint + lateral compliance everywhere (132 parameters), and
``solve --extend auto`` (the selection and its fits) on the 350 records.

Models (each fitted on the training records, held-out records predicted; 3-D distance, mm):
frames only (the nominal robot with its best camera frame and markers), geometric, + joint elasticity
(joint_compliance on every joint), + lateral elasticity (lateral_compliance on every lateral axis too),
and what ``solve --extend auto`` selects. Printed beside DLR's published table (their protocol).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.diagnose import diagnose, session_torques
from lasercal.solver.analysis.stats import folds
from lasercal.solver.formats.justin import write_justin_session
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit, residuals
from lasercal.solver.identify.position import aligned_nominal
from lasercal.solver.kinematics.effects import Extension, combine

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "justin" / "measurements.csv"
DLR = {  # Tenhumberg & Baeuml 2021: mean / std / max mm
    "frames only": (21.33, 9.71, 63.41),
    "geometric": (10.50, 5.74, 36.37),
    "+ joint elasticity": (5.64, 2.57, 12.83),
    "+ lateral elasticity": (3.12, 1.71, 8.23),
}


def elastic(robot, lateral: bool):
    """joint_compliance on every joint (and lateral_compliance on every lateral axis)."""
    real = [j + 1 for j in range(robot.n) if robot.real[j]]
    parts = [Extension("joint_compliance", tuple(real), None, np.zeros(len(real)))]
    if lateral:
        lat = [j + 1 for j in range(robot.n) if not robot.real[j]]
        parts.append(Extension("lateral_compliance", tuple(lat), None, np.zeros(len(lat))))
    return combine(parts)


def models(train, auto: bool):
    """name -> (model, extension) fitted on ``train``."""
    out = {"frames only": (aligned_nominal(train), None)}
    geo = fit(train)
    out["geometric"] = (geo.model, None)
    for name, lat in (("+ joint elasticity", False), ("+ lateral elasticity", True)):
        f = fit(train, elastic(train.robot, lat), suspects=geo.weights == 0)
        out[name] = (f.model, f.extension)
    if auto:
        d = diagnose(train, n_boot=0, k=0)
        ident = d.extended or d.geometric
        out["solve --extend auto"] = (ident.model, ident.extension)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("measurements", nargs="?", default=str(DATA))
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--auto", action="store_true", help="also cross-validate solve --extend auto (slow)")
    a = ap.parse_args()
    folder = Path(tempfile.mkdtemp()) / "justin"
    write_justin_session(a.measurements, folder)
    s = load_session(folder)
    tau, _ = session_torques(s)
    s = replace(s, tau=tau)
    t0 = time.perf_counter()
    full = fit(s, elastic(s.robot, True))
    print(
        f"solve time, {s.m} captures, {full.identifiability.rank} of {len(full.param_names)} parameters "
        f"identifiable (geometry + joint + lateral elasticity): {time.perf_counter() - t0:.1f} s "
        f"({full.iterations} Jacobians)",
        flush=True,
    )
    t0 = time.perf_counter()
    diagnose(s, n_boot=0, k=0)
    print(
        f"solve --extend auto --folds 0 (the selection and its fits), {s.m} captures: "
        f"{time.perf_counter() - t0:.1f} s",
        flush=True,
    )
    if a.folds < 2:
        return
    f = folds(s, a.folds, a.seed)
    dist = {}
    for i in range(a.folds):
        test = f == i
        train, held = s.subset(~test), s.subset(test)
        for name, (model, ext) in models(train, a.auto).items():
            d = np.linalg.norm(residuals(model, ext, held), axis=1)
            dist.setdefault(name, np.full(s.m, np.nan))[test] = d
        print(f"fold {i + 1}/{a.folds} done", flush=True)
    print(f"\n{a.folds}-fold cross-validation by record, {s.m // 2} records x 2 markers (seed {a.seed}), mm")
    print(f"{'model':24s} {'mean':>7s} {'median':>7s} {'max':>7s}   DLR mean / std / max")
    for name, d in dist.items():
        ref = " / ".join(f"{v:.2f}" for v in DLR[name]) if name in DLR else ""
        print(f"{name:24s} {np.mean(d):7.2f} {np.median(d):7.2f} {np.max(d):7.2f}   {ref}")


if __name__ == "__main__":
    main()
