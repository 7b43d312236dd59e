"""Issue 38's coach check on camera sessions: does the plan's promise hold when every capture is measured?

Run: python benchmarks/bench_coach_camera.py [SEEDS [FIRST]]   (default 20 seeds from 0; prints numbers)

As ``bench_coach_workspace.py`` (the thesis's identified Panda as truth, 29 coached captures, the robot
used in its workspace box, held-out error over 200 fresh workspace points), but a camera session: the
operator aims roughly (3 mm per axis) near the coach's target, the camera measures where the spot landed
(0.1 mm per axis, what camera sessions find: docs/sessions.md), the coach and ``solve`` fit the measured
spots with that noise.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import bench_coach_workspace as W
import numpy as np

from lasercal.solver.analysis import design as D
from lasercal.solver.formats.session import Session
from lasercal.solver.formats.tolerances import robot_tolerances
from lasercal.solver.identify.spot import identify_lm
from lasercal.solver.kinematics.aim import polish

AIM, CAMERA = 3.0, 0.1  # mm per axis: the rough aim, the camera's measurement


def guided(seed: int):
    """29 coached camera captures on the true robot: configurations, measured spots, points, the promise."""
    tol = robot_tolerances(W.NOMINAL).with_noise("laser", CAMERA)
    coach = D.Coach(W.NOMINAL, W.LAYOUT, seed=seed, workspace=W.BOX, tolerances=tol)
    rng = np.random.default_rng([seed, 7])
    qs, ts, ps, promise = [], [], [], np.nan
    for _ in range(W.CAPTURES):
        st = coach.status(np.array(qs).reshape(-1, W.NOMINAL.n), k=1)
        promise = st.plan.expected[0]
        hit = st.plan.target[0] + np.r_[rng.normal(0.0, AIM, 2), 0.0]
        qs.append(polish(W.TRUTH, st.suggestion[None], hit)[0])
        ts.append(hit + np.r_[rng.normal(0.0, CAMERA, 2), 0.0])  # what the camera measured
        ps.append(st.plan.point[0])
        coach.update(np.array(qs), np.array(ts))
    return np.array(qs), np.array(ts), ps, promise


def solve(q, target, point) -> object:
    """``lasercal solve``'s fit of a camera session: every capture measured to CAMERA (eq. K1)."""
    m = len(q)
    pts, lines = np.asarray(point, object), np.arange(2, m + 2)
    s = Session(
        Path("."), {}, W.NOMINAL, W.LAYOUT.plane_z, W.TRUTH.aperture[2], W.LAYOUT.points, pts, target,
        np.arange(m, dtype=float), q, None, None, {}, lines, spot_sigma=np.full(m, CAMERA),
    )  # fmt: skip
    ident = identify_lm(s)
    return ident.model, ident


def main(seeds: int = 20, first: int = 0) -> None:
    rows = []
    t0 = time.perf_counter()
    for seed in range(first, first + seeds):
        region = D.use_region(W.NOMINAL, W.LAYOUT, np.random.default_rng([seed, 99]), workspace=W.BOX, n=200)
        q, tgt, pts, promise = guided(seed)
        model, ident = solve(q, tgt, pts)
        err = W.heldout(model, region)
        rows.append((promise, err))
        print(f"  outliers {ident.outliers}, noise {ident.extra['noise']['measured_mm']:.3f} mm", flush=True)
        print(
            f"seed {seed:2d}: plan's last expected {promise:.4f} mm, solve {err:.4f} ({err / promise:.2f}x)",
            flush=True,
        )
    promise, err = np.array(rows).T
    r = err / promise
    print(f"\n{seeds} seeds, {W.CAPTURES} camera captures, {time.perf_counter() - t0:.0f} s")
    print(
        f"measured / plan's last expected_mm: median {np.median(r):.3f}, worst {r.max():.3f} (seed "
        f"{first + int(np.argmax(r))}); seeds over 1.6x: {int(np.sum(r > 1.6))} of {seeds}"
    )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
