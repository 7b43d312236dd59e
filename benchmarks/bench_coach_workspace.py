"""Issue 25's coach check: does the plan's promise hold for the fit ``solve`` makes, on every seed?

Run: python benchmarks/bench_coach_workspace.py [SEEDS [FIRST]]   (default 20 seeds from 0; prints numbers)

Truth = the thesis's identified Panda, nominal = panda, thesis layout (P1-P3), aiming noise 1 mm per
axis, the robot used in a workspace box (:data:`BOX`, mm, base frame: the spots of beams aimed at
points drawn in it). Per seed:

* guided: 29 captures, each the coach's suggestion for that workspace (``Coach(workspace=BOX)``, what
  ``lasercal plan --workspace`` and ``capture`` print), hand-guided by the simulated operator until the
  true beam hits the point up to the noise; the plan's last ``expected_mm`` is the coach's promise
  after the 29th capture;
* random: the thesis protocol with 29 captures (10, 10 and 9 random spread poses at P1-P3);
* both sessions are fitted by ``lasercal solve``'s estimator (:func:`identify_lm` with the robot's
  prior, the same MAP fit as the coach's posterior) and, for comparison, by plain least squares
  (``--prior none``). Held-out error: RMS distance between where the true and the fitted beams meet
  the plane of each of 200 fresh workspace points (another seed).
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.solver.analysis import design as D
from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Session, load_layout
from lasercal.solver.identify.spot import identify_lm, predict_spots
from lasercal.solver.kinematics.aim import polish

TRUTH = load_model("panda_thesis_identified")
NOMINAL = load_model("panda")
LAYOUT = load_layout("thesis")
NOISE = 1.0
CAPTURES = 29
BOX = ((350.0, -250.0, -8.0), (600.0, 250.0, 200.0))


def heldout(model, region) -> float:
    """Held-out RMS spot error (mm) of ``model`` against the truth at the region's configurations."""
    a = predict_spots(TRUTH, region.q, region.target[:, 2])[0]
    b = predict_spots(model, region.q, region.target[:, 2])[0]
    return float(np.sqrt(np.mean(np.sum((a - b)[:, :2] ** 2, axis=1))))


def solve(q, target, point, prior: bool):
    """``lasercal solve``'s fit of captures (MAP with the robot's prior, or plain least squares)."""
    m = len(q)
    s = Session(
        Path("."), {}, NOMINAL, LAYOUT.plane_z, TRUTH.aperture[2], LAYOUT.points, np.asarray(point, object),
        target, np.arange(m, dtype=float), q, None, None, {}, np.arange(2, m + 2),
    )  # fmt: skip
    return identify_lm(s if prior else replace(s, tolerances=None)).model


def guided(seed: int):
    """29 coached captures on the true robot: configurations, targets, points, the last promise."""
    coach = D.Coach(NOMINAL, LAYOUT, seed=seed, workspace=BOX)
    rng = np.random.default_rng([seed, 7])
    qs, ts, ps, promise = [], [], [], np.nan
    for _ in range(CAPTURES):
        st = coach.status(np.array(qs).reshape(-1, NOMINAL.n), k=1, target=np.array(ts).reshape(-1, 3))
        promise = st.plan.expected[0]  # the predicted error once this capture is taken
        hit = st.plan.target[0] + np.r_[rng.normal(0.0, NOISE, 2), 0.0]
        qs.append(polish(TRUTH, st.suggestion[None], hit)[0])  # the operator refines the aim on the robot
        ts.append(st.plan.target[0])
        ps.append(st.plan.point[0])
        coach.update(np.array(qs), np.array(ts))
    post = coach.post
    predicted = D.predicted_error(post, D.use_weight(post, coach.region))[0]
    return np.array(qs), np.array(ts), ps, promise, predicted


def main(seeds: int = 20, first: int = 0) -> None:
    rows = []
    t0 = time.perf_counter()
    for seed in range(first, first + seeds):
        region = D.use_region(NOMINAL, LAYOUT, np.random.default_rng([seed, 99]), workspace=BOX, n=200)
        q, tgt, pts, promise, predicted = guided(seed)
        g_map, g_ls = (heldout(solve(q, tgt, pts, pr), region) for pr in (True, False))
        c = simulate_captures(TRUTH, LAYOUT, 10, NOISE, np.random.default_rng(seed))
        keep = np.arange(CAPTURES)  # 10 + 10 + 9 at P1-P3
        rt = np.array([LAYOUT.points[p] for p in c.point])[keep]
        r_map, r_ls = (heldout(solve(c.q[keep], rt, c.point[keep], pr), region) for pr in (True, False))
        rows.append((promise, predicted, g_map, g_ls, r_map, r_ls))
        print(
            f"seed {seed:2d}: plan's last expected {promise:.3f} mm (posterior {predicted:.3f}) | guided: "
            f"solve {g_map:.3f} ({g_map / promise:.2f}x the promise), --prior none {g_ls:.3f} | random: "
            f"solve {r_map:.3f}, --prior none {r_ls:.3f} | guided/random {g_map / r_map:.3f}",
            flush=True,
        )
    promise, predicted, g_map, g_ls, r_map, r_ls = np.array(rows).T
    ratio = g_map / r_map
    print(f"\n{seeds} seeds, {CAPTURES} captures, workspace box {BOX} mm, {time.perf_counter() - t0:.0f} s")
    print(
        f"guided/random held-out error (both by solve's MAP fit): median {np.median(ratio):.3f}, pooled RMS "
        f"{np.sqrt(np.mean(g_map**2) / np.mean(r_map**2)):.3f}, worst seed {ratio.max():.3f}"
    )
    print(
        f"measured / plan's last expected_mm: median {np.median(g_map / promise):.3f}, worst "
        f"{np.max(g_map / promise):.3f} (seed {first + int(np.argmax(g_map / promise))}); seeds over 1.6x: "
        f"{int(np.sum(g_map > 1.6 * promise))} of {seeds}"
    )
    print(
        f"plain least squares (--prior none) on the same sessions: guided median {np.median(g_ls):.3f} mm, "
        f"worst {g_ls.max():.3f} ({np.max(g_ls / promise):.2f}x the promise); random median "
        f"{np.median(r_ls):.3f} mm"
    )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
