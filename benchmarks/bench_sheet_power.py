"""Issue 52: what a printed sheet costs the diagnosis -- the smallest joint compliance an eye session of
75 captures names, on a sheet laid anywhere against the thesis's base-frame layout.

Run: python benchmarks/bench_sheet_power.py [SEEDS]   (prints a table; no assertions)

Sessions as ``bench_diagnose_sheet.py`` makes them (``lasercal simulate panda_thesis_identified``, every
capture aimed by eye at 0.5 mm per axis, then ``lasercal solve --extend auto --json``), with a compliance
hidden at joint 2 of each size: on the sheet printed for ``--place 450 0 0`` and laid 2 mm, 3 mm and 1 deg
off it (P1-P5, 15 captures each), and on the thesis layout in the base frame (P1-P3, 25 each). 'named' = the
finding is joint 2's compliance (alone or with more), of SEEDS seeds (100 on).
"""

from __future__ import annotations

import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from bench_diagnose_sheet import one, run

SIZES = ("0.5e-4", "0.75e-4", "1e-4", "1.25e-4", "1.5e-4", "2e-4")  # rad/Nm
LAYOUTS = {"sheet laid anywhere": 15, "thesis layout": 25}  # captures per calibration point: 75 each


def named(size: str, layout: str, seeds: int) -> tuple[int, float]:
    """How many of ``seeds`` sessions name joint 2's compliance, and their mean held-out gain, %."""
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        where = "thesis"
        if layout == "sheet laid anywhere":
            run(["sheet", "-o", str(tmp / "sheet"), "--robot", "panda", "--place", "450", "0", "0"])
            where = str(tmp / "sheet" / "layout.yaml")
        effect = ("compliance j2", "joint_compliance", "2", size)
        found = [one(tmp, where, "eye", 100 + s, effect, LAYOUTS[layout]) for s in range(seeds)]
    hits = [g for g in found if g["effect"] == "joint_compliance" and 2 in g["joints"]]
    return len(hits), sum(g["gain_percent"] for g in hits) / max(len(hits), 1)


def main(seeds: int) -> None:
    t0 = time.perf_counter()
    cells = [(size, layout) for size in SIZES for layout in LAYOUTS]
    with ProcessPoolExecutor() as pool:
        done = dict(zip(cells, pool.map(named, *zip(*cells), [seeds] * len(cells))))
    print(f"{'compliance j2 (rad/Nm)':24}" + "".join(f"{k:>30}" for k in LAYOUTS))
    for size in SIZES:
        row = [f"{done[size, k][0]:>3} of {seeds}, gain {done[size, k][1]:5.1f} %" for k in LAYOUTS]
        print(f"{size:24}" + "".join(f"{r:>30}" for r in row))
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
