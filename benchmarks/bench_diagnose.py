"""Diagnosis benchmarks (issue 5): detection power per effect and size, false alarms, speed.

Run: python benchmarks/bench_diagnose.py [--trials N]   (prints numbers; no assertions)

Setup: the thesis's Panda (Table 4.3 identified values) as truth, 150 captures (50 at each
of P1-P3; four points P1-P4 for the point offset), 0.5 mm aiming noise per axis. For each
effect and size, N seeded trials; 'found' means the right effect AND the right joint/point.
The smallest size found in >= 95 % of trials is reported; the false-alarm rate is the share
of clean sessions with any finding.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.diagnose import diagnose
from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Session, load_layout
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.effects import Extension

TRUTH = load_model("panda_thesis_identified")
NOMINAL = load_model("panda")
LAYOUT = load_layout(builtin_dir("layouts") / "thesis.yaml")
LAYOUT4 = replace(LAYOUT, calibration=("P1", "P2", "P3", "P4"), validation=())


def session(effect, seed, layout=LAYOUT, per_point=50):
    c = simulate_captures(TRUTH, layout, per_point, 0.5, np.random.default_rng(seed), effect=effect)
    target = np.array([layout.points[p] for p in c.point])
    return Session(
        Path("."),
        {},
        NOMINAL,
        layout.plane_z,
        TRUTH.aperture[2],
        layout.points,
        c.point,
        target,
        c.t,
        c.q,
        None,
        c.tau,
        {},
        np.arange(len(c.q)) + 2,
    ), c


def spot_shift(effect, c, layout):
    """RMS spot displacement (mm) the effect alone causes at the captured poses."""
    if effect.effect == "reference_point_offset":
        return float(np.hypot(*effect.params))
    q_true = effect.true_q(c.q, c.t, c.tau)
    z = np.array([layout.points[p][2] for p in c.point])
    a, _ = predict_spots(TRUTH, c.q, z)
    b, _ = predict_spots(TRUTH, q_true, z)
    return float(np.sqrt(np.mean(np.sum((a - b)[:, :2] ** 2, 1))))


def make(effect_name, size, rng):
    if effect_name == "joint_compliance":
        return Extension(effect_name, (2,), None, np.array([size]))
    if effect_name == "encoder_eccentricity":
        phi = rng.uniform(0, 2 * np.pi)
        return Extension(effect_name, (3,), None, size * np.array([np.cos(phi), np.sin(phi)]))
    if effect_name == "drift":
        return Extension(effect_name, (4,), None, np.array([size]))
    phi = rng.uniform(0, 2 * np.pi)
    return Extension(effect_name, (), "P2", size * np.array([np.cos(phi), np.sin(phi)]))


SIZES = {
    "joint_compliance": [1e-5, 2e-5, 3e-5, 5e-5, 8e-5],  # rad/Nm on joint 2
    "encoder_eccentricity": [5e-4, 8e-4, 1.2e-3, 2e-3, 3e-3],  # rad amplitude on joint 3
    "drift": [1e-7, 2e-7, 3e-7, 5e-7, 8e-7, 1.2e-6],  # rad/s on joint 4
    "reference_point_offset": [0.3, 0.5, 0.8, 1.2, 2.0],  # mm, point P2 of four
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--effects", default=",".join(SIZES), help="comma-separated effects to scan")
    ap.add_argument("--no-false-alarms", action="store_true", help="skip the clean-session scan")
    args = ap.parse_args()
    n = args.trials
    if not args.no_false_alarms:
        print(f"== false alarms on clean sessions ({2 * n} trials)")
        alarms = 0
        for seed in range(2 * n):
            s, _ = session(None, 1000 + seed)
            alarms += diagnose(s, n_boot=0, k=0).effect != "none"
        print(f"  false-alarm rate {alarms / (2 * n):.3f}")
    for name in args.effects.split(","):
        sizes = SIZES[name]
        print(f"\n== {name}")
        smallest = None
        for size in sizes:
            hits, shifts = 0, []
            for seed in range(n):
                rng = np.random.default_rng(seed)
                eff = make(name, size, rng)
                layout = LAYOUT4 if name == "reference_point_offset" else LAYOUT
                s, c = session(eff, 2000 + seed, layout, 38 if name == "reference_point_offset" else 50)
                d = diagnose(s, n_boot=0, k=0)
                ok = d.effect == name and (
                    d.extension.point == eff.point if eff.point else d.extension.joints == eff.joints
                )
                hits += ok
                shifts.append(spot_shift(eff, c, layout))
            rate = hits / n
            print(f"  size {size:g} ({np.mean(shifts):.2f} mm RMS spot shift): found {rate:.2f}")
            if smallest is None and rate >= 0.95:
                smallest = (size, np.mean(shifts))
        print(
            f"  smallest size found >= 95 %: {smallest[0]:g} ({smallest[1]:.2f} mm)"
            if smallest
            else "  not reached in this grid"
        )
    print(
        "\n== speed: diagnose on 150 captures with the defaults (2000 first-order bootstrap replicates, 10 "
        "full refits, 5-fold CV)"
    )
    s, _ = session(make("joint_compliance", 1e-4, np.random.default_rng(0)), 7)
    t = time.perf_counter()
    d = diagnose(s)
    print(f"  {time.perf_counter() - t:.2f} s (effect {d.effect}, joints {d.extension.joints})")


if __name__ == "__main__":
    main()
