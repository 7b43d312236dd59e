"""Position sessions on URDF arms: exact recovery and held-out error against simulated truth.

Run: PYTHONPATH=... python benchmarks/bench_position.py  (prints one line per arm and noise level)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.solver.analysis.simulate import random_configs, simulate_positions
from lasercal.solver.analysis.stats import cross_validate
from lasercal.solver.formats.positions import position_meta, write_position_session
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.position import sensor_points

TESTS = Path(__file__).resolve().parents[1] / "tests"


def main() -> None:
    import sys
    import tempfile

    sys.path.insert(0, str(TESTS.parent))
    from lasercal.solver.formats.urdf import load_urdf
    from tests.conftest import perturbed  # the tests' truth: perturbed screws, sensor 2.5 m away
    from tests.test_position import DATA

    print(f"{'arm':9} {'noise mm':>8} {'fit RMS':>9} {'CV mean |e|':>12} {'1.596 sigma':>11} {'truth':>10}")
    for name in ("ur5", "arm7", "rail_ur5"):
        for noise in (0.0, 0.01, 0.05):
            rng = np.random.default_rng(11)
            nominal = load_urdf(DATA / f"{name}.urdf")
            truth = perturbed(nominal, rng)
            names = np.tile(np.array(list(truth.targets), dtype=object), 60)
            q = np.repeat(random_configs(nominal, 60, rng), 3, axis=0)
            y = simulate_positions(truth, q, names, noise, rng)
            with tempfile.TemporaryDirectory() as d:
                meta = position_meta(str(DATA / f"{name}.urdf"), truth.targets)
                write_position_session(d, meta, q, y, names)
                s = load_session(d)
                ident = fit(s)
                cv = cross_validate(s, k=5)
            qv = np.repeat(random_configs(nominal, 300, rng), 3, axis=0)
            nv = np.tile(np.array(list(truth.targets), dtype=object), 300)
            e = np.linalg.norm(sensor_points(ident.model, qv, nv) - sensor_points(truth, qv, nv), axis=1)
            print(
                f"{name:9} {noise:8.3f} {ident.rms_mm:9.2e} {cv.errors.mean():12.2e} {1.596 * noise:11.2e} "
                f"{np.sqrt(np.mean(e**2)):10.2e}"
            )


if __name__ == "__main__":
    main()
