"""Start-up and whole-command times of the ``lasercal`` executable (issue 17).

Run: python benchmarks/bench_cli.py [--repeat N]   (prints medians in seconds; no assertions)

Measures, as a user meets them (a new process each time, median of N runs):
- ``lasercal --help`` (goal <= 0.3 s) and ``lasercal COMMAND --help`` for every command (goal <= 0.5 s);
- ``lasercal solve`` of a simulated 150-capture session with its 5-fold cross-validation (goal <= 0.3 s),
  and, in-process, how that splits into importing the solver and the fits themselves.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lasercal.collector.cli.main import COMMANDS


def wall(argv: list[str], repeat: int) -> float:
    """Median wall time (s) of running ``argv`` as a new process."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(argv, capture_output=True, check=False)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    n = ap.parse_args().repeat
    exe = shutil.which("lasercal") or sys.exit("lasercal is not installed (pip install .)")
    print(f"== start-up, median of {n} runs (s)")
    print(f"{'lasercal --help':32} {wall([exe, '--help'], n):6.3f}")
    for c in COMMANDS:
        print(f"{'lasercal ' + c.name + ' --help':32} {wall([exe, c.name, '--help'], n):6.3f}")
    with tempfile.TemporaryDirectory() as tmp:
        s = Path(tmp) / "s"
        subprocess.run(
            [
                exe,
                "simulate",
                "panda_thesis_identified",
                "--layout",
                "thesis",
                "--robot",
                "panda",
                "--per-point",
                "50",
                "--aim-noise",
                "1",
                "--seed",
                "0",
                "-o",
                str(s),
            ],
            check=True,
            capture_output=True,
        )
        times = []
        for i in range(n):
            t0 = time.perf_counter()
            subprocess.run(
                [exe, "solve", str(s), "-o", str(Path(tmp) / f"m{i}.yaml")], check=True, capture_output=True
            )
            times.append(time.perf_counter() - t0)
        print(
            f"\n== lasercal solve, 150 captures, 5-fold cross-validation: {statistics.median(times):.3f} s "
            f"(median of {n})"
        )
        code = (
            "import time; t0 = time.perf_counter()\n"
            "from lasercal.solver.analysis.stats import cross_validate, solve_report\n"
            "from lasercal.solver.formats.session import load_session\n"
            "from lasercal.solver.identify.measurement import fit\n"
            f"t1 = time.perf_counter(); s = load_session({str(s)!r}); t2 = time.perf_counter()\n"
            "g = fit(s); t3 = time.perf_counter()\n"
            "cv = cross_validate(s, 'lm', 5, inlier=g.weights > 0); t4 = time.perf_counter()\n"
            "print(f'imports {t1 - t0:.3f} s, load {t2 - t1:.3f} s, fit {t3 - t2:.3f} s, '\n"
            "      f'5 folds {t4 - t3:.3f} s')"
        )
        out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
        print(f"   in-process: {out.strip()}")


if __name__ == "__main__":
    main()
