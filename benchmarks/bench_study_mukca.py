"""Time the whole MUKCa study (issue 6): four robots, every fold, every candidate effect.

Run: python benchmarks/bench_study_mukca.py [DATA_DIR] [--quick] [-o REPORT_DIR]
(prints numbers; no assertions)

The issue's budget: the four-robot study under 5 minutes on the project machine (2 cores,
shared). DATA_DIR defaults to ../shared/data/mukca next to the repository.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from lasercal.collector.studies.mukca import run_study
from lasercal.collector.studies.options import QUICK, ROBOTS, StudyOptions

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "mukca"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir", nargs="?", default=str(DATA))
    ap.add_argument("--quick", action="store_true", help="fewer simulated replicates (the tests' setting)")
    ap.add_argument("-o", "--output", help="keep the report here (default: a temporary folder)")
    args = ap.parse_args()
    opts = QUICK if args.quick else StudyOptions()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        rep = run_study(args.data_dir, args.output or tmp, ROBOTS, opts)
        wall = time.perf_counter() - t0
    print(f"MUKCa study, {len(ROBOTS)} robots, {opts.bootstrap} replicates, {opts.refits} full refits")
    print(f"{'robot':9} {'captures':>8} {'folds':>5} {'seconds':>8}")
    for r, x in rep["robots"].items():
        print(f"{r:9} {x['captures']:8d} {len(x['calibration']['folds']):5d} {x['seconds']:8.1f}")
    print(f"total {wall:.1f} s (budget 300 s)")


if __name__ == "__main__":
    main()
