"""Issue 25: are the posterior sigmas the spread of the estimates? (Monte Carlo, eq. P4)

Run: python benchmarks/bench_prior_mc.py [REPS]   (default 60 per case; prints numbers, no assertions)

Each replicate draws a true robot from the prior (eq. P1: x = x_0 + R z, R R^T the prior covariance),
simulates a session on it and fits it with ``solve``'s MAP estimator. The errors of the estimate in units
of its posterior sigma should have unit RMS: per parameter, and along the eigen-directions of eq. P5 --
split into those the data determined (posterior / prior sigma < 0.5) and those the prior did (> 0.7).

* laser: the nominal Panda and its tolerances, thesis layout P1-P3, 15 captures each, 1 mm aiming noise;
* position: a UR5 (tests/data/ur5.urdf), 3 tracker targets, 20 poses, 0.02 mm noise.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.simulate import random_configs, simulate_captures, simulate_positions
from lasercal.solver.formats.positions import position_session
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Session, load_layout
from lasercal.solver.formats.tolerances import robot_tolerances
from lasercal.solver.formats.urdf import load_urdf
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.position import PositionParams, target_start
from lasercal.solver.identify.prior import make_prior
from lasercal.solver.identify.spot import laser_prior
from lasercal.solver.kinematics.laser import LaserParams
from lasercal.solver.kinematics.minimal import anchor_heights

ROOT = Path(__file__).resolve().parents[1]


def laser_case(rng: np.random.Generator):
    """A Panda drawn from its prior, a thesis-protocol session on it: (session, truth x, the fit)."""
    nominal, layout = load_model("panda"), load_layout("thesis")
    P = LaserParams(nominal)
    prior = laser_prior(P, robot_tolerances(nominal))
    x = P.x0() + np.linalg.solve(prior.whitening, rng.standard_normal(P.size))
    c = simulate_captures(P.to_model(x), layout, 15, 1.0, rng)
    target = np.array([layout.points[p] for p in c.point])
    s = Session(
        Path("."), {}, nominal, layout.plane_z, None, layout.points, c.point, target, c.t, c.q, None, None,
        {}, np.arange(2, len(c.q) + 2),
    )  # fmt: skip
    return x, fit(s), ["M.z"]  # the aperture along the beam: a gauge


def position_case(rng: np.random.Generator):
    """A UR5 drawn from its prior, tracked at 3 targets in 20 poses."""
    nominal = load_urdf(ROOT / "tests" / "data" / "ur5.urdf")
    names = ["T1", "T2", "T3"]
    P = PositionParams(nominal, names)
    base = target_start(nominal)
    targets = {nm: base + off for nm, off in zip(names, ([60.0, 0, 30], [-40, 50, 20], [0, -60, 40]))}
    x0 = np.zeros(P.size)
    for nm, c in P.col.items():
        x0[c : c + 3] = targets[nm]
    heights = anchor_heights(nominal.screws, base)
    prior = make_prior(
        robot_tolerances(nominal), P.kinds, x0, "position", P.names, nominal.joint_names, heights
    )
    f = prior.finite
    x = x0.copy()
    x[f] = x0[f] + np.linalg.solve(prior.whitening[:, f], rng.standard_normal(int(f.sum())))
    X = np.eye(4)
    X[:3, 3] = [1500.0, -1200.0, 600.0]
    truth = P.to_model(x, X)
    q = np.repeat(random_configs(nominal, 20, rng), 3, axis=0)
    tg = np.tile(np.array(names, dtype=object), 20)
    y = simulate_positions(truth, q, tg, 0.02, rng)
    ident = fit(position_session(nominal, q, y, tg))
    # compare in the fit's own parametrisation: the truth's x in its frames (the sensor frame is free)
    return x, ident, [n for n in P.names if n.startswith("sensor.")]


def check(name: str, case, reps: int) -> None:
    z_par, z_dat, z_pri = [], [], []
    rng = np.random.default_rng(25)
    for _ in range(reps):
        x, ident, skip = case(rng)
        keep = np.array([n not in skip for n in ident.param_names])
        prior = ident.extra["prior"]
        L = prior.whitening[:, keep]
        rows = np.any(L != 0, axis=1)
        L = L[rows]
        C = ident.extra["cov"][np.ix_(keep, keep)]
        e = (ident.estimate - x)[keep]
        z_par.append(e / np.sqrt(np.diag(C)))
        lam, U = np.linalg.eigh(L @ C @ L.T)
        z = U.T @ (L @ e) / np.sqrt(lam)
        r = np.sqrt(lam)
        z_dat += list(z[r < 0.5])
        z_pri += list(z[r > 0.7])

    def rms(a):
        return float(np.sqrt(np.mean(np.square(a)))) if len(a) else float("nan")

    print(
        f"{name}: {reps} truths from the prior; RMS of the standardised errors: per parameter "
        f"{rms(np.concatenate(z_par)):.3f}; along the directions the data determined {rms(z_dat):.3f} "
        f"({len(z_dat)}), the prior {rms(z_pri):.3f} ({len(z_pri)}); 1 when the posterior sigmas are the "
        "spread",
        flush=True,
    )


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 60
    check("laser (Panda, thesis protocol, 1 mm)", laser_case, n)
    check("position (UR5, 3 targets x 20 poses, 0.02 mm)", position_case, n)
