"""Issue 38 item 4: a hands-free camera session on franky-sim, end to end, at the docs' size.

``lasercal sheet --robot fr3 --place 450 0 0``, then ``capture --backend franky --robot fr3 --guide move
--camera fake --yes --per-point 9`` (45 captures; nobody at the keyboard) against a franky-sim server,
then ``solve --json``: the harness of tests/test_collector_franky_sim.py (``camera`` scenario, in a
network namespace of its own where the machine allows one). The fake camera photographs where the nominal
FR3's beam (franky-sim's arm) meets the sheet at the joint angles franky reports.

Prints: wall time, captures, how many the camera measured, commanded moves and the largest joint step,
each measured spot against the nominal FR3's beam at its logged joint angles (error and z-score by its
stated sigma), and solve's fit residual, noise by kind, sheet pose and cross-validated error.
Needs the [sim] extra (franky-control, franky-sim).
Run: python benchmarks/bench_franky_sim_handsfree.py [PER_POINT]  (default 9)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ROOT / "tests" / "test_collector_franky_sim.py"


def run(per_point: int) -> tuple[dict, float, Path]:
    """The ``camera`` scenario in a child process; its report, the wall time (s) and its folder."""
    work = Path(tempfile.mkdtemp(prefix="bench_handsfree_"))
    host = f"127.0.0.{2 + os.getpid() % 250}"
    cmd = [sys.executable, str(HARNESS), "camera", str(work), host, "--per-point", str(per_point)]
    netns = subprocess.run(["unshare", "--net", "true"], capture_output=True).returncode == 0
    if netns:
        cmd = ["unshare", "--net", "--"] + cmd + ["--netns"]
    t = time.monotonic()
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.monotonic() - t
    if done.returncode != 0:
        sys.exit(f"the scenario failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1]), wall, work


def main(per_point: int = 9) -> None:
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.identify.spot import predict_spots

    r, wall, work = run(per_point)
    rows = r["rows"]
    measured = [row for row in rows if row["camera_x"]]
    print(f"hands-free camera session on franky-sim, --per-point {per_point} (folder {work})")
    print(
        f"wall time {wall:.0f} s (capture {r['session_s']:.0f} s), exit codes sheet/capture/solve "
        f"{r['sheet_rc']}/{r['rc']}/{r['solve_rc']}"
    )
    print(
        f"captures {len(rows)}, measured by the camera {len(measured)}, hands-free {r['hands_free']}, "
        f"handed to the operator {r['by_hand']}"
    )
    print(
        f"commanded moves {r['moves']} over {len(r['plans'])} poses, largest joint step "
        f"{r['largest_step']:.3f} rad (--max-step 0.4)"
    )
    if measured:
        layout = load_layout(work / "sheet" / "layout.yaml")
        q = np.array([[float(row[f"q{j}"]) for j in range(1, 8)] for row in measured])
        true = layout.sheet.from_base(predict_spots(load_model("fr3"), q, layout.plane_z)[0])
        xy = np.array([[float(row["camera_x"]), float(row["camera_y"])] for row in measured])
        sigma = np.array([[float(row["camera_sx"]), float(row["camera_sy"])] for row in measured])
        err = xy - true
        rms = np.sqrt((err**2).mean(axis=0))
        print(
            f"spot vs the nominal FR3's beam at the logged q: RMS {rms[0]:.3f}, {rms[1]:.3f} "
            f"mm (x, y), max {np.abs(err).max():.3f} mm; stated sigma median "
            f"{np.median(sigma):.3f} mm; z-score RMS {np.sqrt(((err / sigma) ** 2).mean()):.2f}, "
            f"max {np.abs(err / sigma).max():.2f}"
        )
    if r["solve_rc"] == 0:
        s = r["solve"]
        k, pose = s["noise_by_kind"], s["sheet"]["pose"]
        cv = s["cross_validation"].get("holdout_rms_mm", float("nan"))
        print(
            f"solve: fit residual RMS {s['fit_rms_mm']:.4f} mm; noise by kind: {k['measured']} measured "
            f"{k['measured_mm']} mm per axis (camera {k['camera_mm']}, beyond what it sees "
            f"{k['unseen_mm']}), {k['aimed']} aimed {k['aimed_mm']}"
        )
        print(
            f"solve: sheet at x {pose['x_mm']:.3f}, y {pose['y_mm']:.3f} mm, yaw {pose['yaw_deg']:.4f} deg "
            f"(placed at 450, 0, 0); cross-validated RMS {cv:.3f} mm"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 9)
