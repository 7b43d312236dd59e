"""The printer's scale and the table's tilt as ``solve`` finds them on a camera session, in its own sigmas.

tests/test_fake_world.py asserts that a camera session (the coach's 45 captures, 3 mm rough aiming, the
fake camera) in a world whose printer scaled the sheet and whose table slopes recovers the four numbers
(scale_x, scale_y, tilt_x, tilt_y) within the sigmas ``solve`` reports. This measures the z-scores
(found - true) / sigma over many seeds (each seed a new world draw, new poses and new photos), so that the
test's bound is a quantile of a measured distribution, not a guess: a bound another CPU's rounding (a new
draw) crosses by chance is a red CI with nothing wrong.

Prints per seed the four z-scores and the error of the two scales' difference; then the z-scores' pooled RMS
(1 when the sigmas are right), the quantiles of the largest |z| of a session -- the statistic the test
bounds -- and the difference's error's spread (the test's other bound).

Run: python benchmarks/bench_sheet_scale_camera.py [SEEDS] [FIRST]   (defaults 40, 100; ~25 s a seed)
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

KEYS = ("scale_x", "scale_y", "tilt_x_rad", "tilt_y_rad")


def session_z(work: Path, seed: int) -> np.ndarray:
    """The four z-scores of one camera session in a world drawn with ``seed`` (as the test's fixture), and
    the error of the difference of its two scales (found - true)."""
    from lasercal.collector.cli.main import main
    from lasercal.collector.worlds.record import session_world, true_sheet_pose
    from lasercal.solver.formats.robots import load_model

    d = work / f"s{seed}"
    capture = ["capture", "--layout", str(work / "sheet" / "layout.yaml"), "--robot", "panda"]
    opts = ["--backend", "fake", "--auto", "--per-point", "9", "--aim-noise", "3", "--camera", "fake"]
    effects = ["--effects", "repeatability,print-scale,table-slope", "--seed", str(seed)]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main([*capture, *opts, *effects, "-o", str(d)]) == 0
        assert main(["solve", str(d), "-o", str(work / f"m{seed}.yaml"), "--folds", "0"]) == 0
    model = yaml.safe_load((work / f"m{seed}.yaml").read_text())
    true, _ = true_sheet_pose(session_world(d), load_model("panda"), -8.0)
    z = [(model["sheet"][k] - getattr(true, k)) / model["sheet_std"][k] for k in KEYS]
    found = model["sheet"]["scale_x"] - model["sheet"]["scale_y"]
    return np.array([*z, found - (true.scale_x - true.scale_y)])  # and the two scales' difference's error


def main(n: int = 40, first: int = 100) -> None:
    from lasercal.collector.cli.main import main as cli

    work = Path(tempfile.mkdtemp(prefix="bench_scale_z_"))
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli(["sheet", "-o", str(work / "sheet"), "--place", "450", "0", "0"]) == 0
    print("seed   " + "  ".join(f"{k:>10s}" for k in KEYS) + "   scale difference's error")
    zs = []
    for seed in range(first, first + n):
        z = session_z(work, seed)
        zs.append(z)
        print(f"{seed:4d}   " + "  ".join(f"{v:10.2f}" for v in z[:4]) + f"   {z[4]:+.2e}", flush=True)
    spread, z = np.array(zs)[:, 4], np.array(zs)[:, :4]
    worst = np.abs(z).max(axis=1)
    print(
        f"\n{n} sessions: z RMS per key "
        + ", ".join(f"{k} {v:.2f}" for k, v in zip(KEYS, np.sqrt(np.mean(z**2, 0))))
    )
    print(
        f"pooled z RMS {np.sqrt(np.mean(z**2)):.2f}; largest |z| of a session: "
        f"median {np.median(worst):.2f}, 90 % {np.quantile(worst, 0.9):.2f}, max {worst.max():.2f}"
    )
    # the test's bound: a session's largest |z| under N(0, s^2) per value, s the measured RMS, at 99.9 %
    s = float(np.sqrt(np.mean(z**2)))
    from scipy.stats import norm

    q = s * norm.isf((1 - 0.999**0.25) / 2)
    print(f"99.9 % quantile of a session's largest |z| (4 values, N(0, {s:.2f}^2)): {q:.2f}")
    # the scale difference's error: mean and spread, and its 99.9 % two-sided quantile under N(mean, sd^2)
    m, sd = float(spread.mean()), float(spread.std(ddof=1))
    print(
        f"scale difference's error: mean {m:+.2e}, sd {sd:.2e}, largest |.| {np.abs(spread).max():.2e}; "
        f"99.9 % of |.| under N(mean, sd^2): {abs(m) + sd * norm.isf(0.0005):.2e}"
    )


if __name__ == "__main__":
    main(*map(int, sys.argv[1:]))
