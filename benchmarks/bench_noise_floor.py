"""Issue 51: the distribution of tests/test_position.py::test_noise_floor's figure over seeds.

    python benchmarks/bench_noise_floor.py [--seeds N] [--robots ur5 arm7]

Per robot and seed: the cross-validated held-out error mean over sigma (the test's ``cv.errors.mean() /
sigma``, seed 2 in the test) and the held-out truth RMS over sigma; then their spread and the 0.1 %, 99.9 %
quantiles of a normal fitted to them.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> None:
    from lasercal.solver.analysis.stats import cross_validate
    from lasercal.solver.identify.measurement import fit
    from tests.test_position import heldout_error, session

    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--robots", nargs="+", default=["ur5", "arm7"])
    a = ap.parse_args()
    sigma = 0.02
    for name in a.robots:
        cvm, tr = [], []
        for seed in range(2, 2 + a.seeds):
            with tempfile.TemporaryDirectory() as t:
                s, truth = session(Path(t) / "s", name, 60, sigma, seed)
                ident = fit(s)
                cvm.append(cross_validate(s, k=5).errors.mean() / sigma)
                tr.append(np.sqrt(np.mean(heldout_error(ident.model, truth) ** 2)) / sigma)
            print(f"{name} seed {seed}: cv mean {cvm[-1]:.4f} sigma, truth RMS {tr[-1]:.4f} sigma",
                  flush=True)  # fmt: skip
        for what, v in (("cv mean", np.array(cvm)), ("truth RMS", np.array(tr))):
            m, sd = v.mean(), v.std(ddof=1)
            print(
                f"{name} {what}: {len(v)} seeds {v.min():.4f}-{v.max():.4f}, mean {m:.4f} sd {sd:.4f}; "
                f"normal 0.1 %, 99.9 % quantiles {m - 3.09 * sd:.4f}, {m + 3.09 * sd:.4f}"
            )


if __name__ == "__main__":
    main()
