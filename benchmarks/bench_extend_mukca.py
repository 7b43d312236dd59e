"""Issue 14's must-show table: model extensions on four real Pandas, leave one tool position out.

Run: python benchmarks/bench_extend_mukca.py [DATA_DIR] [--robots panda_1,...]
(prints numbers; no assertions)

Per robot and per held-out tool position: the held-out per-socket spread RMS (mm) of the
nominal model, plain least squares (no outlier test, MUKCa's optimiser), the robust geometric
fit, the extended model (effect selected by the F test and accepted by leave-one-position-out
inside the training positions; the geometric model when nothing is kept) and that extended model
fitted by plain least squares. Then the means, whether extended is never worse than geometric on
the robot's mean, and the worst per-fold ratio of a robust fit to the plain least-squares fit of
the same model (geometric/plain, extended/plain extended; the issue allows 1.02). ext/plain is
the extended model against plain geometry (model choice and outlier test together).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from lasercal.collector.studies.mukca import PLAIN_TOLERANCE, load_robot, loaded_joints, loto
from lasercal.collector.studies.options import QUICK, ROBOTS
from lasercal.solver.analysis.diagnose import session_torques

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "mukca"
COLS = ("nominal", "plain", "geometric", "nested", "nested_plain")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir", nargs="?", default=str(DATA))
    ap.add_argument("--robots", default=",".join(ROBOTS))
    args = ap.parse_args()
    print(
        f"{'robot':8} {'held out':13} {'n':>4} "
        + " ".join(f"{c:>9}" for c in COLS)
        + "  geo/plain ext/pl-ext ext/plain kept"
    )
    summary = []
    with tempfile.TemporaryDirectory() as tmp:
        for robot in args.robots.split(","):
            t0 = time.perf_counter()
            s = load_robot(args.data_dir, robot, tmp)
            common = loaded_joints(session_torques(s, QUICK.payload)[0])
            cv = loto(s, common, None, QUICK)
            for f in cv["folds"]:
                t = f["test"]
                kept = f["nested_label"]
                print(
                    f"{robot:8} {f['held_out']:13} {f['captures']['test']:4d} "
                    + " ".join(f"{t[c]['spread_rms_mm']:9.3f}" for c in COLS)
                    + f"  {f['geometric_over_plain']:9.3f} {f['nested_over_nested_plain']:10.3f}"
                    + f" {f['nested_over_plain']:9.3f} {kept}"
                )
            mean = {c: np.mean([f["test"][c]["spread_rms_mm"] for f in cv["folds"]]) for c in COLS}
            worst = max(max(f["geometric_over_plain"], f["nested_over_nested_plain"]) for f in cv["folds"])
            summary.append((robot, mean, worst, time.perf_counter() - t0))
    print("\nmeans over folds (held-out spread RMS, mm)")
    print(f"{'robot':8} " + " ".join(f"{c:>9}" for c in COLS) + "  ext<=geo  worst robust/plain  seconds")
    for robot, mean, worst, sec in summary:
        ok = "yes" if mean["nested"] <= mean["geometric"] + 1e-12 else "NO"
        flag = "" if worst <= 1 + PLAIN_TOLERANCE else "  > 1.02"
        print(
            f"{robot:8} "
            + " ".join(f"{mean[c]:9.3f}" for c in COLS)
            + f"  {ok:>8}  {worst:18.3f}{flag}  {sec:7.1f}"
        )


if __name__ == "__main__":
    main()
