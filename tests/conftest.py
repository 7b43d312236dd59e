"""Shared fixtures: simulated sessions with known truth (fixed seeds)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session, session_meta, write_session

MUKCA = Path(__file__).resolve().parents[2] / "shared" / "data" / "mukca"


# Franka's DH table (Craig): rows (a_{i-1}, d_i, alpha_{i-1}) in mm; the flange 107 mm along z7 (field notes)
FRANKA_DH = (
    (0, 333, 0),
    (0, 0, -np.pi / 2),
    (0, 316, np.pi / 2),
    (82.5, 0, np.pi / 2),
    (-82.5, 384, -np.pi / 2),
    (0, 0, np.pi / 2),
    (88, 0, np.pi / 2),
)
FRANKA_FLANGE_MM = 107.0


def craig_row(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    """One Craig (modified DH) row (4, 4): Rx(alpha) Tx(a) Rz(theta) Tz(d), from elementary transforms (mm,
    rad), an evaluation independent of lasercal's."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    Rx = np.array([[1, 0, 0, 0], [0, ca, -sa, 0], [0, sa, ca, 0], [0, 0, 0, 1.0]])
    Rz = np.array([[ct, -st, 0, 0], [st, ct, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    Tx, Tz = np.eye(4), np.eye(4)
    Tx[0, 3], Tz[2, 3] = a, d
    return Rx @ Tx @ Rz @ Tz


def franka_flange(q: np.ndarray) -> np.ndarray:
    """Franka's flange (m, 4, 4) mm at q (m, 7) rad: prod Rx(alpha) Tx(a) Rz(q) Tz(d) of the rows, Tz(107)."""
    flange = craig_row(0.0, 0.0, 0.0, FRANKA_FLANGE_MM)
    out = []
    for qi in np.atleast_2d(q):
        T = np.eye(4)
        for (a, d, alpha), qj in zip(FRANKA_DH, qi):
            T = T @ craig_row(alpha, a, qj, d)
        out.append(T @ flange)
    return np.array(out)


def perturbed(nominal, rng, rot=1e-3, mm=1.0):
    """The nominal with every joint screw moved by random eta (rad, mm), a sensor 2.5 m away, 3 targets."""
    from lasercal.simulation import default_sensor, default_targets
    from lasercal.solver.identify.position import eta_sizes
    from lasercal.solver.kinematics.minimal import link_frame, screw_from_eta

    screws = []
    for S, k in zip(nominal.screws, eta_sizes(nominal)):
        scale = np.array([rot, rot, mm, mm]) if k == 4 else np.array([rot, rot])
        screws.append(screw_from_eta(link_frame(S), rng.normal(0, 1, k) * scale)[0])
    return nominal.replace(
        screws=np.array(screws), sensor_pose=default_sensor(), targets=default_targets(nominal, 3)
    )


def make_session(
    tmp: Path, truth_name: str, layout_name: str, per_point: int, noise: float, seed: int, nominal: str
):
    """Simulate, write and reload a session (exercising the file format both ways)."""
    truth = load_model(truth_name)
    layout = load_layout(builtin_dir("layouts") / f"{layout_name}.yaml")
    c = simulate_captures(truth, layout, per_point, noise, np.random.default_rng(seed))
    write_session(tmp, session_meta(nominal, layout, truth.aperture[2]), c.point, c.t, c.q)
    return load_session(tmp), truth, layout


@pytest.fixture(scope="session")
def puma_exact(tmp_path_factory):
    """Thesis Simulation 1: Puma 560, Table 4.1 actual values, 30 configurations per point, no noise."""
    return make_session(
        tmp_path_factory.mktemp("puma"), "puma560_thesis_actual", "puma", 30, 0.0, 1, "puma560"
    )


@pytest.fixture(scope="session")
def panda_noisy(tmp_path_factory):
    """The thesis's Panda experiment: Table 4.3 identified as truth, 15 per point, 1 mm aiming noise."""
    return make_session(
        tmp_path_factory.mktemp("panda"), "panda_thesis_identified", "thesis", 15, 1.0, 2, "panda"
    )


@pytest.fixture(scope="session")
def full_demo(tmp_path_factory):
    """``lasercal demo`` as a user runs it (seed 0, full options; a minute or two): exit code, stdout and
    folder. One run for every test of the figures the README and docs/ show (tests/test_readme.py,
    tests/test_docs_figures.py)."""
    import contextlib
    import io

    from lasercal.collector.cli.main import main

    out = tmp_path_factory.mktemp("full_demo") / "demo"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["demo", "-o", str(out)])
    return code, buf.getvalue(), out
