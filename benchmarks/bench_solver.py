"""Solver benchmarks (issue 2): speed, scaling, accuracy against the best achievable, thesis vs lm.

Run: python benchmarks/bench_solver.py   (prints numbers; no assertions)

Best achievable held-out error: for an unbiased estimator the covariance of the identified
parameters is at least the Cramer-Rao bound sigma^2 (J^T J)^-1 (J the true model's spot
Jacobian at the captured poses, in the identifiable subspace); the held-out spot error of a
new pose then has expected square trace(J_new C J_new^T). Least squares under Gaussian
aiming noise attains the bound asymptotically; we report actual / bound for plain least squares
(``--prior none``) and for ``solve``'s MAP fit, which is biased towards the nominal by its prior and may
beat the bound of unbiased estimators.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Session, load_layout
from lasercal.solver.identify.lsq import identifiability
from lasercal.solver.identify.spot import identify, predict_spots
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.laser import LaserParams

TRUTH = load_model("panda_thesis_identified")
NOMINAL = load_model("panda")
LAYOUT = load_layout(builtin_dir("layouts") / "thesis.yaml")


def session_from(c, tolerances="robot") -> Session:
    target = np.array([LAYOUT.points[p] for p in c.point])
    m = len(c.q)
    return Session(
        Path("."),
        {},
        NOMINAL,
        LAYOUT.plane_z,
        TRUTH.aperture[2],
        LAYOUT.points,
        c.point,
        target,
        c.t,
        c.q,
        None,
        None,
        {},
        np.arange(2, m + 2),
        tolerances=tolerances,
    )


def captures(per_point, noise, seed):
    return simulate_captures(TRUTH, LAYOUT, per_point, noise, np.random.default_rng(seed))


def heldout(n=300, seed=99):
    rng = np.random.default_rng(seed)
    q = np.concatenate(
        [aim(TRUTH, LAYOUT.points[p], n // 3, rng, **LAYOUT.aim_kwargs()) for p in LAYOUT.calibration]
    )
    tgt = np.concatenate([np.repeat(LAYOUT.points[p][None], n // 3, 0) for p in LAYOUT.calibration])
    return q, tgt


def crb_rms(q_fit, target, q_new, tgt_new, sigma):
    """Cramer-Rao held-out RMS (mm) at the true model."""
    P = LaserParams(TRUTH)
    x = P.x0()
    _, _, J = P.spot_jacobian(x, q_fit, target[:, 2])
    m = len(q_fit)
    _, B = identifiability(J.reshape(2 * m, -1), P.names)
    Jz = J.reshape(2 * m, -1) @ B
    _, s, Vt = np.linalg.svd(Jz, full_matrices=False)
    C = sigma**2 * (Vt.T / s**2) @ Vt
    _, _, Jn = P.spot_jacobian(x, q_new, tgt_new[:, 2])
    Jn = Jn @ B  # (k, 2, r)
    return float(np.sqrt(np.mean(np.einsum("kar,rs,kas->k", Jn, C, Jn))))


def main():
    print("== lm on 150 Panda captures (50 per point, 1 mm aiming noise), 5 seeds")
    for seed in range(5):
        s = session_from(captures(50, 1.0, seed))
        t = time.perf_counter()
        r = identify(s, "lm")
        print(
            f"  seed {seed}: {time.perf_counter() - t:.3f} s, {r.iterations} iterations (Jacobian "
            f"evaluations, both stages), converged {r.converged}, fit RMS {r.rms_mm:.3f} mm"
        )

    print("\n== scaling (1 mm noise)")
    base = captures(50, 1.0, 7)
    for m in (150, 1000, 3000, 10000):
        reps = -(-m // 150)
        rng = np.random.default_rng(m)
        q = np.concatenate([base.q] * reps)[:m] + rng.normal(0, 1e-9, (reps * 150, 7))[:m]
        c = type(base)(np.concatenate([base.point] * reps)[:m], np.arange(m, dtype=float), q, None)
        s = session_from(c)
        t = time.perf_counter()
        r = identify(s, "lm", robust=False)
        dt = time.perf_counter() - t
        print(
            f"  {m:6d} captures: {dt:.3f} s, {r.iterations} iterations, "
            f"{1e3 * dt / r.iterations / m * 1000:.2f} us per capture-iteration"
        )

    print(
        "\n== held-out error vs the Cramer-Rao best achievable (1 mm aiming noise, 30 seeds; 300 noise-free "
        "held-out poses)"
    )
    qh, th = heldout()
    for per_point in (15, 50):
        act, bound = {"--prior none": [], "MAP": []}, []
        for seed in range(30):
            c = captures(per_point, 1.0, 100 + seed)
            for label, tol in (("--prior none", None), ("MAP", "robot")):
                r = identify(session_from(c, tol), "lm", robust=False)
                sp, _ = predict_spots(r.model, qh, th[:, 2])
                act[label].append(np.mean(np.sum((sp[:, :2] - th[:, :2]) ** 2, 1)))
            bound.append(crb_rms(c.q, session_from(c).target, qh, th, 1.0) ** 2)
        b = np.sqrt(np.mean(bound))
        for label, e in act.items():
            a = np.sqrt(np.mean(e))
            se = np.std(np.sqrt(e) / np.sqrt(bound), ddof=1) / np.sqrt(len(e))
            print(
                f"  {3 * per_point:4d} captures, {label}: held-out RMS {a:.3f} mm, Cramer-Rao {b:.3f} mm, "
                f"ratio {a / b:.3f} (+- {se:.3f} standard error over seeds)"
            )

    print("\n== thesis vs lm (45 captures, the thesis's setup; 3 seeds; held-out on 300 noise-free poses)")
    for noise in (0.0, 1.0):
        for seed in range(3):
            s = session_from(captures(15, noise, 200 + seed), None)  # the thesis's comparison: no prior
            row = []
            for method in ("thesis", "lm"):
                r = identify(s, method)
                sp, _ = predict_spots(r.model, qh, th[:, 2])
                e = np.linalg.norm(sp[:, :2] - th[:, :2], axis=1)
                row.append(
                    f"{method}: {r.iterations:3d} it {r.seconds:6.3f} s held-out RMS "
                    f"{np.sqrt(np.mean(e**2)):.4f} mm"
                )
            print(f"  noise {noise} seed {seed}: " + " | ".join(row))


if __name__ == "__main__":
    main()
