"""DLR's Agile Justin, 350 shared rows: 5-fold cross-validation by record of four models, and the solve time.

    python benchmarks/bench_justin.py [../shared/data/justin/measurements.csv] [--seed 0] [--folds 5] [--auto]
    python benchmarks/bench_justin.py --folds 0     # the solve times only
    python benchmarks/bench_justin.py --split       # the outside check's path on a split held out here

Solve times: the 700-capture fit of geometry + joint + lateral compliance everywhere (132 parameters), and
``solve --extend auto`` (the selection, its fits and the joint map's cross-validation) on the 350 records.

Models (each fitted on the training records, held-out records predicted; 3-D distance, mm):
frames only (the nominal robot with its best camera frame and markers), geometric, + joint elasticity
(joint_compliance on every joint), + lateral elasticity (lateral_compliance on every lateral axis too),
and what ``solve --extend auto`` selects on the training records: without the joint error map (the
catalogue's effects the diagnosis keeps), with it always, and as each acceptance rule of the map picks on
the training records alone (a nested choice; its own 5-fold cross-validation there): the *plain* rule (a
lower pooled held-out RMS, solve's) and the *CI* rule (the 95 % interval of the fold gains above 0). Printed
beside DLR's published table (their protocol).

``--split``: the position-session check (docs: how work is checked) on records it never saw: H = fold 0 of
a 5-fold split by record with seed 1 (70 records), T = the other 280 -- the records the map's knot step was
chosen on (POSITION_STEP_RAD) -- written as a session folder and a configurations CSV; ``lasercal solve T
-o M.yaml --extend auto --folds 0``, ``lasercal predict M.yaml CFG.csv -o OUT.csv``; the mean 3-D distance
to H's measured positions, with the command's model and with the same model fitted without its map.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.diagnose import diagnose, session_torques
from lasercal.solver.analysis.stats import folds
from lasercal.solver.formats.justin import write_justin_session
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit, residuals
from lasercal.solver.identify.position import aligned_nominal
from lasercal.solver.kinematics.effects import Extension, combine
from lasercal.solver.kinematics.joint_map import (
    POSITION_STEP_RAD,
    JointMap,
    model_extension,
    split_joint_map,
    with_joint_map,
)

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
        base, jm = split_joint_map(ident.extension)
        sus = d.geometric.weights == 0
        without = fit(train, base, suspects=sus) if jm is not None else ident
        moving = [j + 1 for j in range(train.robot.n) if np.ptp(train.q[:, j]) > 0]
        own = JointMap.covering(train.q, moving, POSITION_STEP_RAD, train.robot.joint_names)
        mapped = ident if jm is not None else fit(train, with_joint_map(base, own), suspects=sus)
        out["--extend auto, without map"] = (without.model, without.extension)
        out["--extend auto, with map"] = (mapped.model, mapped.extension)
        rec = d.acceptance["joint_map"]
        h, ci = rec["holdout_rms_mm"], rec["gain_percent_ci95"]
        rules = {"plain": h["with"] < h["without"], "CI": ci is not None and ci[0] > 0}
        print(f"  its map's own 5 folds: {h['without']:.3f} -> {h['with']:.3f} mm RMS, fold gains "
              f"{np.round(rec['gain_percent_folds'], 1).tolist()} %, 95 % CI {np.round(ci, 2).tolist()}; "
              f"kept by solve: {rec['accepted']}; by the plain rule: {rules['plain']}, by the CI rule: "
              f"{rules['CI']}", flush=True)  # fmt: skip
        out["rules"] = rules
    return out


def split_check(measurements: str) -> None:
    """``--split`` (module docstring): the commands on T, predictions for H, mean 3-D error."""
    import subprocess

    tmp = Path(tempfile.mkdtemp())
    write_justin_session(measurements, tmp / "all")
    s = load_session(tmp / "all")
    H = folds(s, 5, 1) == 0
    lines = (tmp / "all" / "captures.csv").read_text().splitlines()
    (tmp / "T").mkdir()
    (tmp / "T" / "session.yaml").write_text((tmp / "all" / "session.yaml").read_text())
    (tmp / "T" / "captures.csv").write_text(
        "\n".join([lines[0]] + [ln for ln, h in zip(lines[1:], H) if not h]) + "\n"
    )
    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h not in ("x", "y", "z")]
    rows = [ln.split(",") for ln, h in zip(lines[1:], H) if h]
    (tmp / "CFG.csv").write_text("\n".join(",".join(r[i] for i in keep) for r in [header] + rows) + "\n")
    t0, c0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    cmd = ["lasercal", "solve", str(tmp / "T"), "-o", str(tmp / "M.yaml"), "--extend", "auto", "--folds", "0"]
    solved = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    seconds = time.perf_counter() - t0
    cpu = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime - c0
    cmd = ["lasercal", "predict", str(tmp / "M.yaml"), str(tmp / "CFG.csv"), "-o", str(tmp / "OUT.csv")]
    subprocess.run(cmd, capture_output=True, text=True, check=True)
    got = np.genfromtxt(tmp / "OUT.csv", delimiter=",", names=True)
    held = s.subset(H)
    pred = np.stack([got["x"], got["y"], got["z"]], axis=1)
    finding = next((ln for ln in solved.splitlines() if ln.startswith("finding")), "")
    mapline = next((ln for ln in solved.splitlines() if ln.startswith("joint_map")), "no map line")
    print(f"split: T {int((~H).sum()) // 2} records, H {int(H.sum()) // 2} (fold 0 of 5 by record, seed 1)")
    print(f"  solve T --extend auto --folds 0: {seconds:.0f} s wall, {cpu:.0f} s CPU; {finding}")
    print(f"  {mapline}")
    print(f"  predict H: mean 3-D error {np.linalg.norm(pred - held.target, axis=1).mean():.3f} mm")
    model = load_model(tmp / "M.yaml")
    base, jm = split_joint_map(model_extension(model.extensions, tmp / "M.yaml", model.n))
    if jm is not None:  # the same finding without its map, fitted on T as solve fits it
        T = load_session(tmp / "T")
        tau, _ = session_torques(T)
        T = replace(T, tau=tau)
        geo = fit(T)
        f = fit(T, base, suspects=geo.weights == 0)
        tau_h, _ = session_torques(held)
        r = residuals(f.model, f.extension, replace(held, tau=tau_h))
        print(f"  the same finding without the map: mean 3-D error {np.linalg.norm(r, axis=1).mean():.3f} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("measurements", nargs="?", default=str(DATA))
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--auto", action="store_true", help="also cross-validate solve --extend auto (slow)")
    ap.add_argument("--split", action="store_true", help="the outside check's commands on a held-out split")
    a = ap.parse_args()
    if a.split:
        return split_check(a.measurements)
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
        fitted = models(train, a.auto)
        rules = fitted.pop("rules", {})
        for name, (model, ext) in fitted.items():
            d = np.linalg.norm(residuals(model, ext, held), axis=1)
            dist.setdefault(name, np.full(s.m, np.nan))[test] = d
        for rule, keep in rules.items():  # what each acceptance rule of the map would have predicted
            pick = dist["--extend auto, with map" if keep else "--extend auto, without map"][test]
            dist.setdefault(f"--extend auto, {rule} rule", np.full(s.m, np.nan))[test] = pick
        print(f"fold {i + 1}/{a.folds} done", flush=True)
    print(f"\n{a.folds}-fold cross-validation by record, {s.m // 2} records x 2 markers (seed {a.seed}), mm")
    print(f"{'model':24s} {'mean':>7s} {'median':>7s} {'max':>7s}   DLR mean / std / max")
    for name, d in dist.items():
        ref = " / ".join(f"{v:.2f}" for v in DLR[name]) if name in DLR else ""
        print(f"{name:24s} {np.mean(d):7.2f} {np.median(d):7.2f} {np.max(d):7.2f}   {ref}")


if __name__ == "__main__":
    main()
