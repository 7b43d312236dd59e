"""Shared fixtures: simulated sessions with known truth (fixed seeds), and what is made once per test run."""

from __future__ import annotations

import contextlib
import fcntl
import io
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session, session_meta, write_session
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim

# Property tests draw new examples on every run; in CI (CI=true) they draw the same ones, so that a red CI
# is a change in the code, not a new draw (a bound on a random error holds in most draws, not in all)
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI") == "true":
    settings.load_profile("ci")

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
MUKCA = SHARED / "mukca"
# What a skip for want of ../shared/data names (each test file says it its own way: a path, a data set's
# folder, "real photos"); under LASERCAL_REQUIRE_SHARED=1 such a skip is a failure, under
# LASERCAL_REQUIRE_ALL=1 (CI, .ci/run) every skip is
SHARED_WORDS = (
    "shared/data",
    "../shared",
    "mukca",
    "justin",
    "ur10-tracker",
    "fr3-camera",
    "franka_description",
    "real-photos",
    "real photos",
)
SHARED_SKIP = (
    f"these tests read the real data in {SHARED} (PROVENANCE.md there), which is not beside this clone or "
    "lacks the data set they read; CI (LASERCAL_REQUIRE_ALL=1) fails instead"
)

# The files that take longest, longest first (``--durations`` with two workers), run before the rest: with
# whole files handed to idle workers in this order (``pytest -n auto``, the README's command, with
# pyproject's ``--dist loadfile --no-loadscope-reorder``), a long file started last would leave the other
# worker idle until it ends.
RUN_FIRST = (
    "test_study_mukca.py",
    "test_vision_real.py",
    "test_identify.py",
    "test_readme.py",
    "test_collector_cli.py",
    "test_prior.py",
    "test_diagnose.py",
    "test_extend.py",
    "test_bad_inputs.py",
    "test_sheet_validate.py",
    "test_sheet.py",
    "test_collector_franky_sim.py",
    "test_report.py",
    "test_sheet_pose.py",
    "test_capture_coach.py",
    "test_docs_api.py",
)

REQUIRE_ALL_SAID = "LASERCAL_REQUIRE_ALL=1 (CI has everything a test needs), and"


def shared_skip(reason: str) -> bool:
    """Whether a skip's reason is the shared data's absence (:data:`SHARED_WORDS`)."""
    return any(w in reason.lower() for w in SHARED_WORDS)


_SHARED_LINE = shared_skip.__code__.co_firstlineno  # where the summary's one line points


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A skip for want of ../shared/data: a failure under ``LASERCAL_REQUIRE_SHARED=1`` (the data vanishing
    must not pass unseen), else one reason for them all, so the summary says it once. Under
    ``LASERCAL_REQUIRE_ALL=1`` (CI, .ci/run: it installs every extra, the browser and the renderer, and has
    ../shared beside the clone) every skip is a failure: a test that needs a browser or MuJoCo's renderer
    must not pass CI by not running."""
    report = (yield).get_result()
    if not report.skipped or hasattr(report, "wasxfail") or not isinstance(report.longrepr, tuple):
        return
    path, line, reason = report.longrepr
    why = reason.removeprefix("Skipped: ")
    if os.environ.get("LASERCAL_REQUIRE_ALL") == "1":
        report.outcome = "failed"
        report.longrepr = f"{REQUIRE_ALL_SAID} this test skipped: {why}"
        return
    if not shared_skip(reason):
        return
    if os.environ.get("LASERCAL_REQUIRE_SHARED") == "1":
        report.outcome = "failed"
        report.longrepr = f"LASERCAL_REQUIRE_SHARED=1, and this test skipped for want of shared data: {why}"
    else:
        report.longrepr = (str(Path(__file__)), _SHARED_LINE, f"Skipped: {SHARED_SKIP}")


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """A whole module skipped at collection (a module-level ``importorskip``: MuJoCo, franky-sim): a failure
    under ``LASERCAL_REQUIRE_ALL=1``, as a test's skip is."""
    report = (yield).get_result()
    required = os.environ.get("LASERCAL_REQUIRE_ALL") == "1"
    if report.skipped and required and isinstance(report.longrepr, tuple):
        report.outcome = "failed"
        why = report.longrepr[2].removeprefix("Skipped: ")
        report.longrepr = f"{REQUIRE_ALL_SAID} this module skipped: {why}"


def pytest_terminal_summary(terminalreporter):
    """One line, whatever the verbosity, when tests skipped for want of ../shared/data."""
    n = sum(
        1
        for r in terminalreporter.stats.get("skipped", ())
        if isinstance(r.longrepr, tuple) and SHARED_SKIP in r.longrepr[2]
    )
    if n:
        terminalreporter.write_line(f"{n} test{'s' if n > 1 else ''} skipped: {SHARED_SKIP}", yellow=True)


def pytest_collection_modifyitems(items):
    """The long files first (:data:`RUN_FIRST`), the others after them in their own order."""
    rank = {name: i for i, name in enumerate(RUN_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(RUN_FIRST)))


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


def angle_error_positions(amp: float, configs: int, seed: int, sigma: float = 0.02):
    """A position session's data: the perturbed UR5 (tests/data/ur5.urdf) whose joint 2 is off by ``amp``
    sin(pi q2 / 2) rad -- an error over the joint's own angle (a gear's, an encoder's), 8 of a joint map's
    0.5 rad knots a period -- at ``configs`` random configurations x 3 targets, ``sigma`` mm noise per axis.

    Returns
    -------
    truth (RobotModel), q (3 configs, 6) rad, target names (3 configs,), positions (3 configs, 3) mm
    """
    from lasercal.solver.analysis.simulate import random_configs, simulate_positions
    from lasercal.solver.formats.urdf import load_urdf

    nominal = load_urdf(Path(__file__).parent / "data" / "ur5.urdf")
    rng = np.random.default_rng(seed)
    truth = perturbed(nominal, rng)
    q = np.repeat(random_configs(nominal, configs, rng), 3, axis=0)
    names = np.tile(np.array(list(truth.targets), dtype=object), configs)
    qt = q.copy()
    qt[:, 1] += amp * np.sin(np.pi * q[:, 1] / 2)
    return truth, q, names, simulate_positions(truth, qt, names, sigma, rng)


def make_session(
    tmp: Path, truth_name: str, layout_name: str, per_point: int, noise: float, seed: int, nominal: str
):
    """Simulate, write and reload a session (exercising the file format both ways)."""
    truth = load_model(truth_name)
    layout = load_layout(builtin_dir("layouts") / f"{layout_name}.yaml")
    c = simulate_captures(truth, layout, per_point, noise, np.random.default_rng(seed))
    write_session(tmp, session_meta(nominal, layout, truth.aperture[2]), c.point, c.t, c.q)
    return load_session(tmp), truth, layout


def heldout_configs(truth, layout, n, seed):
    """n configurations of the true robot aimed exactly at the layout's points (not in the fit)."""
    rng = np.random.default_rng(seed)
    names = list(layout.points)
    qs = [aim(truth, layout.points[nm], -(-n // len(names)), rng, **layout.aim_kwargs()) for nm in names]
    targets = np.concatenate([np.repeat(layout.points[nm][None], len(q), 0) for nm, q in zip(names, qs)])
    return np.concatenate(qs)[:n], targets[:n]


def heldout_error(model, q, targets):
    spots, _ = predict_spots(model, q, targets[:, 2])
    return np.linalg.norm(spots[:, :2] - targets[:, :2], axis=1)


def made_once(tmp_path_factory, name: str, make) -> Path:
    """The folder ``name`` that ``make(folder)`` fills, made once per test run however many pytest-xdist
    workers ask for it: the workers share the parent of their own temporary folders, and a lock makes
    the others wait for the first. A failed ``make`` leaves no mark, and the next one tries again."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    root = tmp_path_factory.getbasetemp()
    root = root.parent if worker else root  # the parent of a plain run's folder is shared by every run
    folder, done = root / name, root / f"{name}.done"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.is_file():
            folder.mkdir(exist_ok=True)
            make(folder)
            done.touch()
    return folder


class Terminal(io.StringIO):
    """A captured stream that says it is a terminal (where the progress bar shows)."""

    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="session")
def full_demo(tmp_path_factory):
    """``lasercal demo -o DIR`` as a user runs it (seed 0, the full demo, about a minute), once per test
    run: its exit code, what it printed on stdout and on stderr (a terminal), and its folder."""
    from lasercal.collector.cli.main import main

    def make(folder: Path) -> None:
        out, err = io.StringIO(), Terminal()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["demo", "-o", str(folder / "demo")])
        (folder / "stdout.txt").write_text(out.getvalue())
        (folder / "stderr.txt").write_text(err.getvalue())
        (folder / "code.txt").write_text(str(code))

    folder = made_once(tmp_path_factory, "full_demo", make)
    read = [(folder / f"{name}.txt").read_text() for name in ("code", "stdout", "stderr")]
    return int(read[0]), read[1], read[2], folder / "demo"


def made_session(tmp_path_factory, name: str, truth_name: str, layout_name: str, *args):
    """:func:`make_session` (per_point, noise, seed, nominal) written once per test run (see
    :func:`made_once`) and read back by every worker: the session, the truth and the layout."""
    folder = made_once(tmp_path_factory, name, lambda d: make_session(d, truth_name, layout_name, *args))
    return (
        load_session(folder),
        load_model(truth_name),
        load_layout(builtin_dir("layouts") / f"{layout_name}.yaml"),
    )


@pytest.fixture(scope="session")
def puma_exact(tmp_path_factory):
    """Thesis Simulation 1: Puma 560, Table 4.1 actual values, 30 configurations per point, no noise."""
    return made_session(
        tmp_path_factory, "puma_exact", "puma560_thesis_actual", "puma", 30, 0.0, 1, "puma560"
    )


@pytest.fixture(scope="session")
def puma_heldout(tmp_path_factory, puma_exact):
    """100 configurations of Simulation 1's true Puma aimed at its points, none in the fit (seed 11), made
    once for every test that scores a fit on them (aiming them costs as much as the fit's session)."""
    _, truth, layout = puma_exact

    def make(folder: Path) -> None:
        np.savez(folder / "heldout.npz", *heldout_configs(truth, layout, 100, 11))

    with np.load(made_once(tmp_path_factory, "puma_heldout", make) / "heldout.npz") as f:
        return f["arr_0"], f["arr_1"]


@pytest.fixture(scope="session")
def panda_noisy(tmp_path_factory):
    """The thesis's Panda experiment: Table 4.3 identified as truth, 15 per point, 1 mm aiming noise."""
    return made_session(
        tmp_path_factory, "panda_noisy", "panda_thesis_identified", "thesis", 15, 1.0, 2, "panda"
    )


@pytest.fixture(scope="session")
def sheet(tmp_path_factory):
    """An A4 sheet's layout.yaml (markers, crosses), placed at 450, 0, 0 as `lasercal sheet --place` does."""
    from lasercal.vision.sheet import design_sheet, write_layout

    path = tmp_path_factory.mktemp("sheet") / "layout.yaml"
    write_layout(path, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 0.0, "yaw_deg": 0.0})
    return path
