"""``lasercal validate`` on the simulated robot: its time, and its figures against the simulated truth.

Run: python benchmarks/bench_validate.py [-n 60]   (prints numbers; no assertions)

1. docs/sessions.md's case: ``capture --backend fake --auto --per-point 15`` on the thesis layout (truth
   panda_thesis_identified, 1 mm aiming noise, seed 0), ``solve``, then ``validate`` of the nominal and of
   the identified model at P4 with N configurations: wall and CPU time of each validate, its spot
   statistics, and how far each measured spot lies from where the true beam met the table at the
   measured joint angles (the fake camera's photos, rendered and measured).
2. issue 33's walkthrough: ``sheet --place 450 0 0``, ``simulate --sheet-pose 455 -3 1.5``, ``solve``,
   ``validate`` at P6 of the nominal (``--sheet-from model.yaml``) and of the model, ``report``: each run's
   mean error beside the truth's own prediction (the true robot in its own frame, the sheet at its true
   pose) at the configurations photographed, and the report's verdict.
"""

from __future__ import annotations

import argparse
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout
from lasercal.solver.formats.table import csv_rows
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.sheet import SheetPose


def run(exe: str, *args) -> tuple[str, float, float]:
    """Run ``lasercal ARGS``: its standard output, wall time (s) and CPU time of the process (s)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
    if done.returncode:
        sys.exit(f"lasercal {' '.join(map(str, args))}: {done.stderr.strip()}")
    out = done.stdout
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return out, wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def table(folder: Path, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The measured joint angles (k, n) rad and spots (k, 2) mm of a validation.csv."""
    rows = csv_rows(folder / "validation.csv")
    h = rows[0][1]
    q = np.array([[float(r[h.index(f"q{j}")]) for j in range(1, n + 1)] for _, r in rows[1:]])
    xy = np.array([[float(r[h.index("x_mm")]), float(r[h.index("y_mm")])] for _, r in rows[1:]])
    return q, xy


def thesis_case(exe: str, tmp: Path, n: int) -> None:
    s, m = tmp / "session", tmp / "model.yaml"
    cap = ["capture", "--layout", "thesis", "--robot", "panda", "--backend", "fake", "--auto"]
    run(exe, *cap, "--per-point", 15, "-o", s)
    run(exe, "solve", s, "-o", m)
    truth, z = load_model("panda_thesis_identified"), load_layout("thesis").plane_z
    print(f"== validate at P4, {n} configurations, fake backend and camera (thesis layout, session of 45)")
    for name, model in (("nominal", "panda"), ("identified", m)):
        v = tmp / f"val_{name}"
        out, wall, cpu = run(exe, "validate", model, "--point", "P4", "-n", n, "--backend", "fake", "-o", v)
        q, xy = table(v, 7)
        d = np.linalg.norm(xy - predict_spots(truth, q, z)[0][:, :2], axis=1)
        print(f"{name:10} {wall:5.1f} s wall, {cpu:5.1f} s CPU; {out.strip().splitlines()[-1]}")
        print(f"{'':10} photos measured {d.mean():.4f} mm mean ({d.max():.4f} max) from the true beam")


def sheet_case(exe: str, tmp: Path, n: int) -> None:
    sheet, s, m = tmp / "sheet", tmp / "sheet_session", tmp / "sheet_model.yaml"
    layout = sheet / "layout.yaml"
    run(exe, "sheet", "-o", sheet, "--robot", "panda", "--place", 450, 0, 0)
    run(exe, "simulate", "panda_thesis_identified", "--layout", layout, "--sheet-pose", 455, -3, 1.5, "-o", s)
    out, _, _ = run(exe, "solve", s, "-o", m)
    print("\n== issue 33's walkthrough: " + next(ln for ln in out.splitlines() if "the sheet lies" in ln))
    truth, true = load_model(s / "truth.yaml"), SheetPose(455.0, -3.0, 1.5)
    lay = load_layout(layout)
    found, p6 = load_model(m).sheet, lay.points["P6"][:2]
    runs = {"sheet_nominal": ["panda", "--sheet-from", m], "sheet_calibrated": [m]}
    for name, model in runs.items():
        v = tmp / name
        where = ["--layout", layout, "--point", "P6", "-n", n, "--backend", "fake"]
        out, wall, cpu = run(exe, "validate", *model, *where, "-o", v)
        q, xy = table(v, 7)
        measured = np.linalg.norm(found.from_base(xy) - p6, axis=1)
        predicted = np.linalg.norm(true.from_base(predict_spots(truth, q, lay.plane_z)[0]) - p6, axis=1)
        apart = np.abs(measured - predicted).max()
        print(
            f"{name:12} {wall:5.1f} s wall, {cpu:5.1f} s CPU: error at P6 {measured.mean():.3f} mm mean (max "
            f"{measured.max():.3f}); the truth's prediction {predicted.mean():.3f} mm mean (max "
            f"{predicted.max():.3f}), {apart:.4f} mm apart at most"
        )
    runs = [tmp / name for name in runs]
    run(exe, "report", s, *runs, "-o", tmp / "report", "--bootstrap", 200)
    text = (tmp / "report" / "index.html").read_text()
    print("report: " + re.search(r'<p id="verdict"><b>(.*?)</b>', text).group(1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=60, help="configurations per validation run")
    n = ap.parse_args().n
    exe = shutil.which("lasercal", path=str(Path(sys.executable).parent)) or shutil.which("lasercal")
    if exe is None:
        sys.exit("lasercal is not installed (pip install .)")
    with tempfile.TemporaryDirectory() as tmp:
        thesis_case(exe, Path(tmp), n)
        sheet_case(exe, Path(tmp), n)


if __name__ == "__main__":
    main()
