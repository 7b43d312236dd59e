"""Pose sessions (issue 39): the built-in ur10, the ipa importer, several sessions with their own frames,
register, predict, the joint error map. Truth: an independent DH evaluation, the raw file's values,
simulated sessions of a known robot (exact data recover it)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lasercal.collector.cli.main import main
from lasercal.solver.formats.ipa import UR_JOINTS, read_series
from lasercal.solver.formats.poses import PoseSession, frames_from_pose, load_pose_session, pose_from_frames
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.tolerances import robot_tolerances
from lasercal.solver.identify.fullpose import estimate_frames
from lasercal.solver.identify.poses import errors, fit_poses, session_frames
from lasercal.solver.kinematics.effects import Extension
from lasercal.solver.kinematics.gravity import gravity_torques
from lasercal.solver.kinematics.joint_map import JointMap
from lasercal.solver.kinematics.minimal import link_frame, screw_from_eta
from lasercal.solver.kinematics.poe import exp6, fk

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "ur10-tracker"
needs_data = pytest.mark.skipif(
    not (DATA / "Series_B").is_dir(), reason="ur10-tracker data not beside the clone"
)
DH = [
    (127.3, 0.0, np.pi / 2),
    (0.0, -612.0, 0.0),
    (0.0, -572.3, 0.0),
    (163.941, 0.0, np.pi / 2),
    (115.7, 0.0, -np.pi / 2),
    (92.2, 0.0, 0.0),
]  # fmt: skip  (UR's d, a mm, alpha rad)


def rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    m = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]], "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]]}
    return np.array(m.get(axis, [[c, -s, 0], [s, c, 0], [0, 0, 1]]))


def dh_flange(q: np.ndarray) -> np.ndarray:
    """The UR10's flange by the textbook product Rz(q) Tz(d) Tx(a) Rx(alpha), one joint at a time."""
    T = np.eye(4)
    for (d, a, al), qi in zip(DH, q):
        A = np.eye(4)
        A[:3, :3] = rot("z", qi) @ rot("x", al)
        A[:3, 3] = [a * np.cos(qi), a * np.sin(qi), d]
        T = T @ A
    return T


def test_ur10_forward_kinematics_is_urs_dh_table():
    model = load_model("ur10")
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (20, 6))
    T = fk(model.screws, model.ee_pose, q)
    assert max(np.abs(T[i] - dh_flange(q[i])).max() for i in range(20)) < 1e-9
    assert robot_tolerances(model).offset_mm == 5.0


def test_ur10_gravity_torques_are_the_potential_energys_gradient():
    model = load_model("ur10")
    mass = np.array([lk.mass for lk in model.links])
    com = np.array([lk.com for lk in model.links])

    def energy(q):  # sum m g z of every centre of mass (J), link i carried by joints 1..i
        from lasercal.solver.kinematics.poe import poe_chain

        chain = poe_chain(model.screws, q[None])[0]
        return sum(
            9.81e-3 * m * (chain[i + 1, :3, :3] @ c + chain[i + 1, :3, 3])[2]
            for i, (m, c) in enumerate(zip(mass, com))
        )

    q = np.array([0.3, -1.2, 1.1, -0.7, 0.9, 0.2])
    num = np.array([(energy(q + 1e-6 * e) - energy(q - 1e-6 * e)) / 2e-6 for e in np.eye(6)])
    assert np.allclose(gravity_torques(model, q[None])[0], num, atol=1e-6)
    assert abs(num[1]) > 50  # the shoulder carries the arm: tens of Nm


# ----------------------------------------------------------------------------- the importer
@needs_data
def test_import_keeps_the_raw_values_and_reads_euler_xyz(tmp_path):
    series = tmp_path / "Series_B"
    series.mkdir()
    lines = (DATA / "Series_B" / "measurements_joint_configurations.csv").read_text().splitlines()[:41]
    (series / "measurements_joint_configurations.csv").write_text("\n".join(lines) + "\n")
    assert main(["import-ipa", str(series), "-o", str(tmp_path / "S")]) == 0
    s = load_pose_session(tmp_path / "S")
    header = lines[1 - 1].split(";")
    raw = np.array([[float(c.replace(",", ".")) for c in ln.split(";")] for ln in lines[1:]])
    col = {h: i for i, h in enumerate(header)}
    assert np.array_equal(s.q, raw[:, [col[h] for h in UR_JOINTS]])
    assert np.allclose(
        s.T[:, :3, 3], raw[:, [col["measurement_x"], col["measurement_y"], col["measurement_z"]]]
    )
    for i in range(len(raw)):  # R = Rx(rx) Ry(ry) Rz(rz): intrinsic x-y'-z'' of the degrees given
        a, b, c = np.radians(raw[i, [col["measurement_rx"], col["measurement_ry"], col["measurement_rz"]]])
        assert np.abs(s.T[i, :3, :3] - rot("x", a) @ rot("y", b) @ rot("z", c)).max() < 1e-12
    assert np.allclose(s.std[:, 3], np.radians(raw[:, col["measurement_std_rx"]]))
    assert np.allclose(s.temperature, raw[:, col["measurement_temperature"]])


@needs_data
def test_euler_xyz_makes_the_probe_agree_with_the_robot():
    """The convention: with 'XYZ' the nominal UR10 and one pair of fitted frames reproduce 300 poses of series
    B to the robot's accuracy (< 1 mm, < 2 mrad RMS); the extrinsic reading 'xyz' is 10x worse in rotation."""
    s = read_series(DATA / "Series_B")
    pick = np.arange(0, len(s["q"]), 5)[:300]
    model = load_model("ur10")
    al = estimate_frames(model, s["q"][pick], s["T"][pick])
    assert al.rms_pos_mm < 1.0 and al.rms_rot_rad < 2e-3
    raw = np.array([Rotation.from_matrix(R).as_euler("XYZ") for R in s["T"][pick, :3, :3]])
    T = s["T"][pick].copy()
    T[:, :3, :3] = Rotation.from_euler("xyz", raw).as_matrix()
    assert estimate_frames(model, s["q"][pick], T).rms_rot_rad > 10 * al.rms_rot_rad


def test_pose_rows_round_trip():
    T = np.tile(np.eye(4), (50, 1, 1))
    rng = np.random.default_rng(1)
    T[:, :3, :3] = Rotation.random(50, random_state=rng).as_matrix()
    T[:, :3, 3] = rng.normal(0, 1000, (50, 3))
    assert np.abs(frames_from_pose(pose_from_frames(T)) - T).max() < 1e-9


# ----------------------------------------------------------------------------- several sessions, one robot
def truth_and_sessions(rng, n_sessions=3, m=60, compliance=None, noise=0.0, span=np.pi):
    """A perturbed UR10 (axes ~2 mrad, positions ~2 mm) and sessions of its poses, each with its own sensor
    placement and tool mounting."""
    nominal = load_model("ur10")
    screws = np.array(
        [screw_from_eta(link_frame(S), rng.normal(0, [2e-3, 2e-3, 2.0, 2.0]))[0] for S in nominal.screws]
    )
    truth = nominal.replace(screws=screws)
    ext = None if compliance is None else Extension("joint_compliance", (2, 3), None, np.array(compliance))
    sessions, frames = [], []
    for k in range(n_sessions):
        X = exp6(np.r_[rng.normal(0, 0.5, 3), rng.normal(0, 1000, 3)])
        M = nominal.ee_pose @ exp6(np.r_[rng.normal(0, 0.3, 3), rng.normal(0, 50, 3)])
        q = rng.uniform(-span, span, (m, 6))
        q[:, 1] = rng.uniform(-2.8, -0.3, m) if span > 1.3 else -1.55 + q[:, 1]
        # the torques of the nominal's gravity model: what the fit uses (its masses are not identified)
        qt = q if ext is None else ext.true_q(q, None, gravity_torques(nominal, q))
        T = X @ fk(truth.screws, M, qt)
        if noise:
            T = T @ exp6_rows(rng.normal(0, [noise / 1000] * 3 + [noise] * 3, (m, 6)))
        sessions.append(session(f"s{k}", nominal, q, T))
        frames.append((X, M))
    return nominal, truth, ext, sessions, frames


def exp6_rows(xi):
    return np.array([exp6(x) for x in xi])


def session(name, robot, q, T) -> PoseSession:
    m = len(q)
    t = np.arange(m, dtype=float)
    return PoseSession(
        Path(name), {}, robot, q, T, None, t, None, np.arange(2, m + 2), [], [], robot_tolerances(robot)
    )


def test_several_sessions_with_their_own_frames_recover_the_robot_exactly():
    rng = np.random.default_rng(7)
    nominal, truth, _, sessions, frames = truth_and_sessions(rng)
    fit = fit_poses(sessions, nominal)
    q = rng.uniform(-np.pi, np.pi, (200, 6))
    for s, (X, M) in zip(sessions, frames):
        Xf, Mf = fit.frames[s.name]
        p, r = errors(session_frames(fit.model, q, Xf, Mf), X @ fk(truth.screws, M, q))
        assert p.max() < 1e-6 and r.max() < 1e-9
    assert max(e[0].max() for e in fit.errors.values()) < 1e-6


def test_joint_compliance_is_recovered_across_sessions():
    rng = np.random.default_rng(8)
    c = [-1.2e-5, -0.9e-5]
    nominal, truth, _, sessions, _ = truth_and_sessions(rng, compliance=c)
    fit = fit_poses(sessions, nominal, Extension("joint_compliance", (2, 3), None, np.zeros(2)))
    assert np.allclose(fit.effects[0].params, c, rtol=1e-6, atol=1e-12)


def test_register_recovers_a_moved_tracker_and_remounted_tool():
    rng = np.random.default_rng(9)
    nominal, truth, _, sessions, _ = truth_and_sessions(rng, n_sessions=1)
    calibrated = fit_poses(sessions, nominal).model
    X = exp6(np.r_[0.3, -0.2, 1.0, 2500.0, -800.0, 300.0])
    M = calibrated.ee_pose @ exp6(np.r_[0.01, 0.02, -0.5, 3.0, -2.0, 10.0])
    q = rng.uniform(-np.pi, np.pi, (40, 6))
    moved = session("moved", nominal, q, X @ fk(calibrated.screws, M, q))
    reg = fit_poses([moved], calibrated, joints=False)
    Xf, Mf = reg.frames["moved"]
    assert np.abs(Xf - X).max() < 1e-6 and np.abs(Mf - M).max() < 1e-6
    assert np.array_equal(reg.model.screws, calibrated.screws)


def test_noise_weights_follow_the_data():
    """Position noise 0.05 mm and rotation noise 0.05 mrad per axis: the fit reports what it sees."""
    rng = np.random.default_rng(10)
    nominal, _, _, sessions, _ = truth_and_sessions(rng, m=150, noise=0.05)
    fit = fit_poses(sessions, nominal)
    dof = 1 - fit.fit.identifiability.rank / (6 * 450)
    assert 0.05 * np.sqrt(dof) * 0.9 < fit.sigma_pos < 0.05 * 1.1
    assert 0.05e-3 * np.sqrt(dof) * 0.85 < fit.sigma_rot < 0.05e-3 * 1.15


def test_joint_map_is_the_piecewise_linear_interpolation_of_its_knots():
    q = np.linspace(-1, 1, 41)[:, None] * np.ones((1, 6))
    jm = JointMap.covering(q, joints=(2, 5), step=0.25)
    vals = np.random.default_rng(2).normal(0, 1e-4, jm.size)
    jm = jm.with_params(vals)
    dq = jm.correction(q)
    k2 = jm.start[0] + 0.25 * np.arange(jm.counts[0])
    assert np.allclose(dq[:, 1], np.interp(q[:, 1], k2, vals[: jm.counts[0]]), atol=1e-15)
    assert np.all(dq[:, [0, 2, 3, 5]] == 0)


def test_a_joint_map_error_is_learnt_and_transfers_to_a_new_session():
    """Truth: a 0.3 mrad error on joint 2 that varies over 0.2 rad of its angle. Fitted on two sessions, the
    map predicts a third one (frames registered on its own poses) 5x better than geometry alone."""
    rng = np.random.default_rng(11)
    nominal, truth, _, sessions, frames = truth_and_sessions(rng, m=250)

    def err(q):
        return 3e-4 * np.sin(2 * np.pi * q[:, 1] / 0.2)

    for k, s in enumerate(sessions):
        qt = s.q.copy()
        qt[:, 1] += err(s.q)
        X, M = frames[k]
        sessions[k] = session(s.name, nominal, s.q, X @ fk(truth.screws, M, qt))
    jm = JointMap.covering(np.vstack([s.q for s in sessions]), joints=(2,), step=0.025)
    geo = fit_poses(sessions[:2], nominal)
    mapped = fit_poses(sessions[:2], nominal, joint_map=jm)
    held = sessions[2]
    e = [errors(session_frames(r.model, held.q, *next(iter(r.frames.values())), r.effects), held.T)[0].mean()
         for r in (fit_poses([held], f.model, joints=False) for f in (geo, mapped))]  # fmt: skip
    assert e[1] < e[0] / 5


# ----------------------------------------------------------------------------- the commands
def write_session(folder: Path, q, T):
    from lasercal.solver.formats.poses import pose_meta, write_pose_session

    write_pose_session(folder, pose_meta("ur10"), q, T, temperature=np.full(len(q), 21.5))


def test_solve_extend_joint_map_names_the_map_and_predict_applies_it(tmp_path):
    """``solve --extend joint_map`` (the name the model file and the code use) fits the map alone; register
    on one half of a third session and predict the other: 5x better than the geometry (the truth of
    test_a_joint_map_error_is_learnt_and_transfers_to_a_new_session: 0.3 mrad on joint 2 over 0.2 rad)."""
    rng = np.random.default_rng(11)
    nominal, truth, _, sessions, frames = truth_and_sessions(rng, m=250)
    for (X, M), s in zip(frames, sessions):
        qt = s.q.copy()
        qt[:, 1] += 3e-4 * np.sin(2 * np.pi * s.q[:, 1] / 0.2)
        write_session(tmp_path / s.name, s.q, X @ fk(truth.screws, M, qt))
        if s.name == "s2":  # the held-out session in two halves: register on one, predict the other
            write_session(tmp_path / "half1", s.q[:125], (X @ fk(truth.screws, M, qt))[:125])
            cfg = tmp_path / "cfg.csv"
            cfg.write_text(
                "q1,q2,q3,q4,q5,q6\n" + "".join(",".join(map(repr, r.tolist())) + "\n" for r in s.q[125:])
            )
            want = (X @ fk(truth.screws, M, qt))[125:]
    mean = {}
    for ext in ("none", "joint_map"):
        m, r, out = (tmp_path / f"{ext}{k}" for k in (".yaml", "_r.yaml", ".csv"))
        args = ["solve", str(tmp_path / "s0"), str(tmp_path / "s1"), "-o", str(m), "--extend", ext]
        assert main(args + ["--folds", "0"]) == 0
        assert set(load_model(m).extensions) == ({"joint_map"} if ext == "joint_map" else set())
        assert main(["register", str(m), str(tmp_path / "half1"), "-o", str(r)]) == 0
        assert main(["predict", str(r), str(cfg), "-o", str(out)]) == 0
        got = np.genfromtxt(out, delimiter=",", names=True)
        pred = frames_from_pose(np.stack([got[k] for k in ("x", "y", "z", "rx", "ry", "rz")], axis=1))
        mean[ext] = errors(pred, want)[0].mean()
    assert mean["joint_map"] < mean["none"] / 5


def test_solve_register_predict_round_trip(tmp_path, capsys):
    rng = np.random.default_rng(12)
    nominal, truth, _, sessions, frames = truth_and_sessions(rng, n_sessions=2, m=40)
    for s in sessions:
        write_session(tmp_path / s.name, s.q, s.T)
    assert (
        main(
            [
                "solve",
                str(tmp_path / "s0"),
                str(tmp_path / "s1"),
                "-o",
                str(tmp_path / "m.yaml"),
                "--json",
            ]
        )
        == 0
    )
    # --json: the fit and the leave-one-session-out folds (each fold its own fit; exact data, so the held-out
    # error is the solver's tolerance), in mm and mrad
    got = json.loads(capsys.readouterr().out)
    loso = got["leave_one_session_out"]
    assert [f["held"] for f in loso["folds"]] == ["s0", "s1"] and got["units"] == {
        "position": "mm",
        "rotation": "mrad",
    }
    assert loso["position_mm"] < 1e-4 and max(s["fitted_position_mm"] for s in got["sessions"]) < 1e-4
    X = exp6(np.r_[0.1, 0.2, -0.3, 1500.0, 200.0, -900.0])
    M = nominal.ee_pose @ exp6(np.r_[0.0, 0.0, 0.4, 1.0, 2.0, 80.0])
    q = rng.uniform(-np.pi, np.pi, (60, 6))
    T = X @ fk(truth.screws, M, q)
    write_session(tmp_path / "new", q[:30], T[:30])
    assert (
        main(["register", str(tmp_path / "m.yaml"), str(tmp_path / "new"), "-o", str(tmp_path / "r.yaml")])
        == 0
    )
    cfg = tmp_path / "cfg.csv"
    cfg.write_text(
        "q1,q2,q3,q4,q5,q6,temperature\n"
        + "".join(",".join(repr(float(v)) for v in r) + ",21.5\n" for r in q[30:])
    )
    assert main(["predict", str(tmp_path / "r.yaml"), str(cfg), "-o", str(tmp_path / "out.csv")]) == 0
    out = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    assert np.allclose(out["temperature"], 21.5)
    pred = frames_from_pose(np.stack([out[k] for k in ("x", "y", "z", "rx", "ry", "rz")], axis=1))
    p, r = errors(pred, T[30:])
    assert p.max() < 1e-5 and r.max() < 1e-8


def test_extend_auto_on_one_session_keeps_the_joint_compliance_it_hides(tmp_path, capsys):
    """One session (its three blocks of rows stand in for sessions): a hidden compliance on joints 2, 3 (twice
    the UR10's), 0.01 mm / 0.01 mrad noise: auto keeps it, and it predicts the held-out blocks 3x better."""
    rng = np.random.default_rng(13)
    nominal, truth, ext, sessions, _ = truth_and_sessions(rng, 1, 120, [-2e-5, -2e-5], noise=0.01, span=0.8)
    write_session(tmp_path / "s", sessions[0].q, sessions[0].T)
    out = tmp_path / "m.yaml"
    assert main(["solve", str(tmp_path / "s"), "-o", str(out), "--extend", "auto", "--folds", "0"]) == 0
    text = capsys.readouterr().out
    table = text.split("held out (")[1].split("the choice made inside")[0].splitlines()[1:]
    held = {ln.split(":")[0].strip(): float(ln.split(":")[1].split()[0]) for ln in table}
    kept = text.split("kept: ")[1].split("\n")[0]
    # compliance alone on the hidden joints (not compliance + map: the session has no map)
    assert kept == "joint compliance (joints 2,3)" and held[kept] < held["geometric"] / 3
    # issue 52: each block held out chose it from the other two alone, and its gain is the outer folds'
    folds = text.split("inside each fold")[1].split("held out with")[0].splitlines()[1:]
    assert len(folds) == 3 and all(kept in ln for ln in folds), folds
    nested = text.split("held out with each fold's own choice: ")[1]
    assert float(nested.split()[0]) == held[kept] and "3 of 3 folds chose" in nested
    assert set(load_model(out).extensions) == {"joint_compliance"}


def test_extend_auto_on_two_sessions_chooses_inside_each_fold_over_the_training_sessions_blocks(
    tmp_path, capsys
):
    """Issue 52: with two sessions each outer fold trains on one and chooses over its three blocks of rows."""
    rng = np.random.default_rng(13)
    nominal, truth, ext, sessions, _ = truth_and_sessions(rng, 2, 90, [-2e-5, -2e-5], noise=0.01, span=0.8)
    for k, s in enumerate(sessions):
        write_session(tmp_path / f"s{k}", s.q, s.T)
    out = tmp_path / "m.yaml"
    args = ["solve", str(tmp_path / "s0"), str(tmp_path / "s1"), "-o", str(out), "--extend", "auto", "--json"]
    assert main(args) == 0
    said = capsys.readouterr()
    got = json.loads(said.out)  # --json: stdout is the JSON alone, and nothing says it was ignored
    assert "--json" not in said.err
    kept, folds, nested = got["kept"], got["fold_choices"], got["nested"]
    assert kept == "joint compliance (joints 2,3)" and [f["chose"] for f in folds] == [kept, kept], got
    assert (nested["agree"], nested["needed"], got["folds_disagreed"]) == (2, 1, False)
    # the figure stood by is the outer folds' own choices', each fold's held-out error of its own fit
    assert nested["position_mm"] == pytest.approx(np.mean([f["position_mm"] for f in folds]), rel=1e-12)
    assert nested["position_mm"] < nested["geometric_position_mm"] / 3
    assert [s["name"] for s in got["sessions"]] == ["s0", "s1"] and got["output"] == str(out)
    assert set(load_model(out).extensions) == {"joint_compliance"}


def test_extend_auto_keeps_the_geometry_when_the_folds_chose_otherwise(tmp_path, capsys, monkeypatch):
    """Issue 52: the session's best model is kept only when all but one outer fold chose it from its own
    training blocks; here two of three folds are made to choose the geometry: the geometry is kept, and
    the held-out figure is each fold's own choice's."""
    from lasercal.solver.analysis import pose_cv

    rng = np.random.default_rng(13)
    nominal, truth, ext, sessions, _ = truth_and_sessions(rng, 1, 120, [-2e-5, -2e-5], noise=0.01, span=0.8)
    write_session(tmp_path / "s", sessions[0].q, sessions[0].T)
    made = pose_cv.nested_choices
    monkeypatch.setattr(pose_cv, "nested_choices", lambda c, *a: [made(c, *a)[0], c[0].label, c[0].label])
    out = tmp_path / "m.yaml"
    assert main(["solve", str(tmp_path / "s"), "-o", str(out), "--extend", "auto", "--folds", "0"]) == 0
    text = capsys.readouterr().out
    assert text.split("\nkept: ")[1].split("\n")[0] == "geometric"
    assert "1 of 3 folds chose joint compliance (joints 2,3) (2 needed)" in text
    assert "joint compliance (joints 2,3), best held out, is not named: the folds disagreed" in text
    assert not load_model(out).extensions
    table = text.split("held out (")[1].split("the choice made inside")[0].splitlines()[1:]
    held = {ln.split(":")[0].strip(): float(ln.split(":")[1].split()[0]) for ln in table}
    folds = [
        float(ln.split(", ")[-2].split()[0]) for ln in text.split("inside each fold")[1].splitlines()[1:4]
    ]
    nested = float(text.split("held out with each fold's own choice: ")[1].split()[0])
    assert nested == pytest.approx(np.mean(folds), abs=2e-3) and held["geometric"] > nested > min(
        held.values()
    )


@needs_data
def test_the_real_data_recipe_runs_as_written(tmp_path, monkeypatch):
    """docs/real-data.md's UR10 block, command by command as written, on every eighth row of the three
    series (copied into tmp_path: the data root is the one thing swapped, to keep it short): C's halves are
    its rows in order, poses.csv predicts C2's rows, and the model fitted on A and B and placed on C1
    predicts C2 better than the nominal UR10 placed on C1 (frames only)."""
    import shlex
    import subprocess

    from lasercal.solver.analysis.pose_cv import predict_session, register

    doc = Path(__file__).resolve().parents[1] / "docs" / "real-data.md"
    block = doc.read_text().split("## A UR10 and a laser tracker", 1)[1].split("```bash\n", 1)[1]
    lines = [ln.split("  #")[0].strip() for ln in block.split("```", 1)[0].splitlines()]
    lines = [ln for ln in lines if ln.startswith(("lasercal ", "cut "))]
    data = tmp_path / "ur10-tracker"
    for name in ("Series_A", "Series_B", "Series_C"):
        (src,) = (DATA / name).glob("measurements_*.csv")
        rows = src.read_text().splitlines()
        (data / name).mkdir(parents=True)
        (data / name / src.name).write_text("\n".join(rows[:1] + rows[1::8]) + "\n")
    monkeypatch.chdir(tmp_path)
    for line in lines:
        line = line.replace("../shared/data/ur10-tracker", str(data))
        if line.startswith("cut "):
            subprocess.run(line, shell=True, check=True)
        else:
            assert main(shlex.split(line)[1:]) == 0, line
    whole = load_pose_session(tmp_path / "C1"), load_pose_session(tmp_path / "C2")
    c = read_series(data / "Series_C")
    assert np.array_equal(np.vstack([s.q for s in whole]), c["q"]) and whole[0].m == len(c["q"]) // 2
    got = np.genfromtxt(tmp_path / "poses.csv", delimiter=",", names=True)
    assert np.array_equal(got["t"], whole[1].t)  # C2's rows, in order
    pred = frames_from_pose(np.stack([got[k] for k in ("x", "y", "z", "rx", "ry", "rz")], axis=1))
    model_err = errors(pred, whole[1].T)[0].mean()
    nominal = register(load_model("ur10"), whole[0])
    nominal_err = errors(predict_session(nominal, whole[1]), whole[1].T)[0].mean()
    # the claim (docs/real-data.md, fitted on A+B, placed on C's first half, C's second half held out):
    # 0.362 mm, nominal 0.908. On every eighth row the figure spreads with the rows taken: over the 8
    # offsets (rows[1 + k::8], benchmarks/bench_recipe_rows.py) 0.347-0.402 mm, mean 0.370 sd 0.018
    # (this test's offset 0: 0.377), the nominal 0.839-0.947, the ratio 0.373-0.434 (mean 0.406 sd 0.018).
    # Bounds: the normal fits' 99.9 % quantiles, 0.425 mm and 0.462 (0.8 x the nominal passed 0.74 mm,
    # twice the claim)
    assert model_err < 0.43, (model_err, nominal_err)
    assert model_err < 0.47 * nominal_err, (model_err, nominal_err)
