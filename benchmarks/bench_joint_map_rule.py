"""Which rule keeps a position session's joint error map: the pooled held-out RMS (solve's) or the 95 %
interval of the fold gains above 0 -- on simulated sessions whose truth is known, scored on new data.

Each session: the perturbed UR5 of the tests whose joint 2 is off by AMP sin(pi q2 / 2) rad (an error of the
joint's own angle; AMP 0: no map effect), M configurations x 3 targets, 0.02 mm noise; 200 more
configurations held back. ``diagnose`` (``solve --extend auto``'s, 5 folds by configuration) gives both
rules' decisions; the geometry with and without the map, fitted on the session, predicts the 200 new
configurations (3-D RMS, mm): the truth of whether keeping the map was right.

    nice python benchmarks/bench_joint_map_rule.py               # the grid of docs/position.md (~30 min)
    nice python benchmarks/bench_joint_map_rule.py AMP M SEED0 SEED1
"""

from __future__ import annotations

import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.diagnose import diagnose, session_torques
from lasercal.solver.formats.positions import position_meta, write_position_session
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit, residuals
from lasercal.solver.kinematics.joint_map import POSITION_STEP_RAD, JointMap, split_joint_map, with_joint_map

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.conftest import angle_error_positions  # noqa: E402  (the tests' session with an angle error)

URDF = ROOT / "tests" / "data" / "ur5.urdf"
NEW = 200
GRID = [(0.0, 60, range(10)), (0.0, 600, range(6)), (1e-5, 200, range(5)), (3e-5, 200, range(15)),
        (5e-5, 200, range(8))]  # fmt: skip


def one(amp: float, m: int, seed: int) -> tuple[bool, bool, float]:
    """(kept by the pooled RMS, kept by the CI rule, the map's gain on the new configurations %)."""
    truth, q, names, y = angle_error_positions(amp, m + NEW, seed)
    folder = Path(tempfile.mkdtemp()) / "S"
    write_position_session(folder, position_meta(str(URDF), truth.targets), q, y, names)
    s = load_session(folder)
    s = replace(s, tau=session_torques(s)[0])
    train, new = s.subset(np.arange(s.m) < 3 * m), s.subset(np.arange(s.m) >= 3 * m)
    d = diagnose(train, n_boot=0, k=5)
    rec = d.acceptance["joint_map"]
    h, ci = rec["holdout_rms_mm"], rec["gain_percent_ci95"]
    base = split_joint_map(d.extension)[0] if d.extension is not None else None
    sus = d.geometric.weights == 0
    moving = [j + 1 for j in range(train.robot.n) if np.ptp(train.q[:, j]) > 0]
    jm = JointMap.covering(train.q, moving, POSITION_STEP_RAD)
    fits = fit(train, base, suspects=sus), fit(train, with_joint_map(base, jm), suspects=sus)
    e = [np.sqrt(np.mean(np.sum(residuals(f.model, f.extension, new) ** 2, axis=1))) for f in fits]
    gain = 100 * (e[0] - e[1]) / e[0]
    plain, strict = bool(h["with"] < h["without"]), bool(ci[0] > 0)
    print(f"amp {amp:g} rad, {m} configurations, seed {seed}: "
          f"folds {h['without']:.4f} -> {h['with']:.4f} mm, "
          f"gains {np.round(rec['gain_percent_folds'], 1).tolist()} %, CI {np.round(ci, 1).tolist()}; "
          f"pooled rule {'keeps' if plain else 'drops'}, CI rule {'keeps' if strict else 'drops'}; "
          f"new configurations {e[0]:.4f} -> {e[1]:.4f} mm ({gain:+.1f} %)", flush=True)  # fmt: skip
    return plain, strict, gain


def main() -> None:
    grid = (
        GRID
        if len(sys.argv) < 5
        else [(float(sys.argv[1]), int(sys.argv[2]), range(*map(int, sys.argv[3:5])))]
    )
    for amp, m, seeds in grid:
        r = np.array([one(amp, m, sd) for sd in seeds])
        for name, col in (("pooled RMS", 0), ("CI above 0", 1)):
            kept = r[:, col] > 0
            print(f"  amp {amp:g}, {m} configurations, {len(r)} sessions: {name} keeps {kept.sum()}"
                  f"; the map's gain on new configurations where kept {np.round(r[kept, 2], 1).tolist()} %, "
                  f"where dropped {np.round(r[~kept, 2], 1).tolist()} %", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
