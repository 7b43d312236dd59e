"""Full-pose POE calibration (thesis Section 2.3) from circle-point measurements, and on real FR3 data."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.linalg import expm, logm
from scipy.spatial.transform import Rotation

from lasercal.collector.cli.main import build_parser
from lasercal.solver.errors import FormatError, IdentificationError, LasercalError, ModelError
from lasercal.solver.formats.fullpose_io import read_pose_csv
from lasercal.solver.formats.robots import load_model
from lasercal.solver.identify.fullpose import (
    PoseParams,
    _error_jacobian,
    accuracy,
    calibrate_fullpose,
    cross_validate,
    default_target,
    estimate_frames,
    fit_fullpose,
    format_table,
    pose_errors,
    simulate_circlepoint,
    with_target,
)
from lasercal.solver.kinematics.poe import fk, inv_T

FR3 = Path(
    os.environ.get(
        "LASERCAL_FR3_DATA", Path(__file__).resolve().parents[2] / "shared" / "data" / "fr3-camera"
    )
)
FLANGE = np.array(
    [[1.0, 0, 0, 88], [0, -1, 0, 0], [0, 0, -1, 926], [0, 0, 0, 1]]
)  # Franka DH at q = 0, flange d = 107 mm


def hat(xi):
    w, v = xi[:3], xi[3:]
    return np.array([[0, -w[2], w[1], v[0]], [w[2], 0, -w[0], v[1]], [-w[1], w[0], 0, v[2]], [0, 0, 0, 0]])


def robots(kind):
    """(nominal, truth) with M at the same target: the thesis's Puma (Table 4.1) or Panda (Table 4.3)."""
    nom, tru = {"puma": ("puma560", "puma560_thesis_actual"), "panda": ("panda", "panda_thesis_identified")}[
        kind
    ]
    nom, tru = load_model(nom), load_model(tru)
    tgt = default_target(nom)
    return with_target(nom, tgt), with_target(tru, tgt), tgt


def measured(truth, tgt, g, noise, seed):
    return simulate_circlepoint(truth, g, 6, np.radians(20), noise, np.random.default_rng(seed), tgt).poses()


# ------------------------------------------------------------------ the error model and its Jacobian
def test_pose_error_is_the_matrix_log():
    rng = np.random.default_rng(0)
    Ta, Tn = expm(hat(rng.normal(0, 0.5, 6))), expm(hat(rng.normal(0, 0.5, 6)))
    L = logm(Ta @ np.linalg.inv(Tn)).real
    y = pose_errors(Ta[None], Tn[None])[0]
    assert np.allclose(y, [L[2, 1], L[0, 2], L[1, 0], *L[:3, 3]], atol=1e-10)


def test_jacobian_against_finite_differences():
    nom, tru, _ = robots("panda")
    P = PoseParams(nom)
    rng = np.random.default_rng(1)
    q = rng.uniform(nom.limits[:, 0], nom.limits[:, 1], (5, nom.n))
    x = rng.normal(0, 0.02, P.size)
    x[P.slice_M] = rng.normal(0, 0.1, 6) * [1, 1, 1, 50, 50, 50]
    Ta = fk(tru.screws, tru.ee_pose, q) @ expm(
        hat(rng.normal(0, 0.2, 6))
    )  # far from the model: y is not small
    T, J = P.jacobian(x, q)
    # eq. 2.3.28: [dT T^-1]^vee, by central differences of log(T(x + h) T(x)^-1)
    h = 1e-6
    num = np.stack(
        [
            (pose_errors(P.poses(x + h * e, q), T) - pose_errors(P.poses(x - h * e, q), T)) / (2 * h)
            for e in np.eye(P.size)
        ],
        -1,
    )
    assert np.abs(J - num).max() < 1e-5 * max(1, np.abs(J).max())
    # the residual Jacobian dy/dx = -J_l(-y)^-1 J, used by least_squares
    D = _error_jacobian(pose_errors(Ta, T), J)
    num = np.stack(
        [
            (pose_errors(Ta, P.poses(x + h * e, q)) - pose_errors(Ta, P.poses(x - h * e, q))) / (2 * h)
            for e in np.eye(P.size)
        ],
        -1,
    )
    assert np.abs(D - num).max() < 1e-5 * max(1, np.abs(D).max())


# ------------------------------------------------------------------ calibration of simulated robots
@pytest.mark.parametrize("kind", ["puma", "panda"])
def test_exact_recovery_without_noise(kind):
    nom, tru, tgt = robots(kind)
    q, T = measured(tru, tgt, 30, 0.0, 7)
    cal = calibrate_fullpose(nom, q, T)
    f = cal.fit
    assert f.converged and f.identifiability.rank == 4 * nom.n + 6 and not f.identifiability.unidentifiable
    assert cal.before.position[0] > 1.0 and cal.after.position[2] < 1e-6
    qv, _ = measured(tru, tgt, 30, 0.0, 8)  # fresh configurations
    Tt, Tc = fk(tru.screws, tru.ee_pose, qv), fk(cal.model.screws, cal.model.ee_pose, qv)
    assert (
        np.abs(Tt[:, :3, 3] - Tc[:, :3, 3]).max() < 1e-6
        and np.abs(Tt[:, :3, :3] - Tc[:, :3, :3]).max() < 1e-9
    )
    assert (
        np.abs(cal.model.screws - tru.screws).max() < 1e-8
    )  # the minimal POE is unique: the screws themselves


@pytest.mark.parametrize("kind", ["puma", "panda"])
def test_noisy_calibration_reaches_the_sensor_level(kind):
    nom, tru, tgt = robots(kind)
    q, T = measured(tru, tgt, 40, 0.01, 9)
    cal = calibrate_fullpose(nom, q, T)
    assert cal.fit.converged and cal.before.position[0] > 5.0
    assert cal.after.position[0] < 0.03 and np.all(cal.after.euler[:, 0] < 0.03)  # mm, deg
    qv, Tv = measured(tru, tgt, 40, 0.01, 10)  # validation poses, measured the same way
    acc = accuracy(Tv, fk(cal.model.screws, cal.model.ee_pose, qv))
    assert acc.position[0] < 0.04 and np.all(acc.euler[:, 0] < 0.04)
    # the identified model against the truth, off the measurement noise of the poses
    Tt, Tc = fk(tru.screws, tru.ee_pose, qv), fk(cal.model.screws, cal.model.ee_pose, qv)
    assert np.linalg.norm(Tt[:, :3, 3] - Tc[:, :3, 3], axis=1).mean() < 0.03
    table = format_table([("nominal", cal.before), ("calibrated", cal.after)]).splitlines()
    assert len(table) == 9 and table[2].split()[-4:] == [
        "calibrated",
        *(f"{v:.5f}" for v in cal.after.position),
    ]


def test_standard_errors_match_the_scatter():
    nom, tru, tgt = robots("puma")
    d = simulate_circlepoint(tru, 30, 6, np.radians(20), 0.0, np.random.default_rng(11), tgt)
    q, T0 = d.poses()
    x_true = fit_fullpose(nom, q, T0).estimate
    z = []
    for seed in range(3):  # the same configurations, new sensor noise
        noisy = dataclasses.replace(
            d, points=d.points + np.random.default_rng(100 + seed).normal(0, 0.01, d.points.shape)
        )
        _, T = noisy.poses()
        f = fit_fullpose(nom, q, T)
        z.append((f.estimate - x_true) / np.array([f.std_errors[k] for k in f.param_names]))
    chi2 = np.mean(np.square(z))
    assert 0.3 < chi2 < 3.0


def test_unidentifiable_combinations_stay_at_their_start():
    nom, tru, tgt = robots("puma")
    q, T = measured(tru, tgt, 30, 0.0, 12)
    q[:, 0] = 0.3  # joint 1 never moves: its axis is not seen, only the fixed transform it makes
    T = fk(tru.screws, tru.ee_pose, q)
    f = fit_fullpose(nom, q, T)
    idf = f.identifiability
    assert (
        idf.rank == 4 * nom.n + 6 - 4
        and len(idf.unidentifiable) == 4
        and idf.singular_values[idf.rank] < 1e-9
    )
    assert all(np.isfinite(v) for v in f.std_errors.values())
    assert f.converged and np.abs(pose_errors(T, fk(f.model.screws, f.model.ee_pose, q))).max() < 1e-9


def test_estimate_frames_recovers_base_and_tool():
    nom = load_model("panda").replace(ee_pose=FLANGE)
    rng = np.random.default_rng(4)
    q = rng.uniform(nom.limits[:, 0], nom.limits[:, 1], (20, 7))
    X, Y = np.eye(4), np.eye(4)
    X[:3, :3], X[:3, 3] = Rotation.from_rotvec([0.1, -0.2, 2.0]).as_matrix(), [-600, 500, 20]
    Y[:3, :3], Y[:3, 3] = Rotation.from_euler("z", 90, degrees=True).as_matrix(), [94.5, -9, 40.55]
    al = estimate_frames(nom, q, X @ fk(nom.screws, FLANGE, q) @ Y)
    assert al.converged and np.abs(al.base - X).max() < 1e-8 and np.abs(al.tool - Y).max() < 1e-8


# ------------------------------------------------------------------ bad input
def test_bad_input():
    nom, tru, tgt = robots("puma")
    q, T = measured(tru, tgt, 10, 0.0, 1)
    with pytest.raises(LasercalError, match="10 configurations but 9 measured poses"):
        fit_fullpose(nom, q, T[:9])
    with pytest.raises(ModelError, match="7 joints but the robot has 6"):
        fit_fullpose(nom, np.zeros((10, 7)), T)
    with pytest.raises(IdentificationError, match="at least 5 configurations"):
        fit_fullpose(nom, q[:4], T[:4])
    with pytest.raises(ModelError, match="no end-effector frame"):
        PoseParams(load_model("puma560"))
    with pytest.raises(IdentificationError, match="2 <= K <= 10"):
        cross_validate(nom, q, T, k=1)
    with pytest.raises(IdentificationError, match="single axis"):
        q1 = np.zeros((6, 6))
        q1[:, 5] = np.linspace(0, 1, 6)
        estimate_frames(nom, q1, fk(tru.screws, tru.ee_pose, q1))
    with pytest.raises(LasercalError, match="m >= 3"):
        simulate_circlepoint(tru, 5, 2, 0.3, 0.0, np.random.default_rng(0))
    with pytest.raises(LasercalError, match="range"):
        simulate_circlepoint(tru, 5, 6, np.radians(170), 0.0, np.random.default_rng(0))


# ------------------------------------------------------------------ command line
def run(argv):
    a = build_parser(argv[0]).parse_args(argv)
    return a.func(a)


def test_cli_simulate_then_calibrate(tmp_path, capsys):
    m, out = tmp_path / "m.csv", tmp_path / "id.yaml"
    assert (
        run(
            [
                "simulate-fullpose",
                "--robot",
                "puma560_thesis_actual",
                "--configs",
                "20",
                "--noise",
                "0.01",
                "--seed",
                "3",
                "-o",
                str(m),
            ]
        )
        == 0
    )
    assert (
        run(["fullpose", str(m), "--robot", "puma560", "-o", str(out), "--folds", "3", "--method", "circle"])
        == 0
    )
    text = capsys.readouterr().out
    assert "absolute position [mm]" in text and "3-fold cross-validation" in text
    model = load_model(out)
    assert model.ee_pose is not None and model.identification["identifiability"]["rank"] == 30
    with pytest.raises(LasercalError, match="exists and is kept"):  # no silent overwrite
        run(["fullpose", str(m), "--robot", "puma560", "-o", str(out), "--json", "--method", "circle"])
    assert (
        run(
            [
                "fullpose",
                str(m),
                "--robot",
                "puma560",
                "-o",
                str(out),
                "--json",
                "--method",
                "circle",
                "--force",
            ]
        )
        == 0
    )
    rep = json.loads(capsys.readouterr().out)
    assert rep["accuracy"]["after"]["position_mm"]["mean"] < 0.05 and "frames" in rep
    m.write_text(m.read_text().replace("config,", "cfg,"))
    with pytest.raises(FormatError, match="missing column 'config'"):
        run(["fullpose", str(m), "--robot", "puma560", "-o", str(out), "--force"])


# ------------------------------------------------------------------ real data: FR3 camera poses
needs_fr3 = pytest.mark.skipif(
    not (FR3 / "poses.csv").is_file(),
    reason=f"real FR3 data not found at {FR3} (shared/data/fr3-camera beside the repository, or "
    "LASERCAL_FR3_DATA)",
)


@needs_fr3
def test_fr3_real_data_cross_validated():
    d = read_pose_csv(FR3 / "poses.csv", 7)
    assert len(d.q) == 114
    nom = load_model("panda").replace(ee_pose=FLANGE)
    cv = cross_validate(nom, d.q, d.T, k=5, seed=0, estimate=True)
    assert cv.calibrated_test.position[0] < 0.4 * cv.nominal_test.position[0]
    assert cv.calibrated_test.euler[2, 0] < 0.5 * cv.nominal_test.euler[2, 0]
    assert all(f["rank"] == 34 for f in cv.per_fold)
    al = calibrate_fullpose(nom, d.q, d.T, estimate=True).alignment
    # the author's hand measurement: camera about (94.5, -9, 40.55) mm from the flange, turned 90 deg about z
    assert np.linalg.norm(al.tool[:3, 3] - [94.5, -9, 40.55]) < 10
    assert abs(Rotation.from_matrix(al.tool[:3, :3]).as_euler("xyz", degrees=True)[2] - 90) < 5


@needs_fr3
def test_fr3_cli_reads_poses(tmp_path, capsys):
    out = tmp_path / "fr3.yaml"
    assert run(["fullpose", str(FR3 / "poses.csv"), "--robot", "panda", "-o", str(out)]) == 0
    assert "114 poses" in capsys.readouterr().out
    ident = yaml.safe_load(out.read_text())["identification"]
    assert (
        ident["accuracy"]["after"]["position_mm"]["mean"] < ident["accuracy"]["before"]["position_mm"]["mean"]
    )


def test_pose_csv_errors(tmp_path):
    p = tmp_path / "poses.csv"
    cols = "q1,q2," + ",".join(f"r{i}{j}" for i in range(1, 4) for j in range(1, 4)) + ",x,y,z"
    p.write_text(cols + "\n0,0,1,0,0,0,1,0,0,0,1,1,2,3\n0,0,1,0,0,0,2,0,0,0,1,1,2,3\n")
    with pytest.raises(FormatError, match="not a rotation matrix") as e:
        read_pose_csv(p)
    assert e.value.line == 3
    p.write_text(cols + "\n0,0,1,0,0,0,1,0,0,0,1,1,2\n")
    with pytest.raises(FormatError, match="13 values but 14 columns") as e:
        read_pose_csv(p)
    assert e.value.line == 2
    p.write_text(cols + ",t\n0,0,1,0,0,0,1,0,0,0,1,1,2,3,0\n")
    with pytest.raises(FormatError, match="unknown column"):
        read_pose_csv(p)
    p.write_text(cols + "\n0,0,1,0,0,0,1,0,0,0,1,1,2,3\n")
    with pytest.raises(FormatError, match="look like metres"):  # every origin within 5 mm of the base
        read_pose_csv(p)
    p.write_text(cols + "\n0,0,1,0,0,0,1,0,0,0,1,100,200,300\n")
    with pytest.raises(FormatError, match="2 joint columns but the robot has 7"):
        read_pose_csv(p, 7)
    T = read_pose_csv(p, 2).T[0]
    assert np.allclose(T, [[1, 0, 0, 100], [0, 1, 0, 200], [0, 0, 1, 300], [0, 0, 0, 1]])
    assert np.allclose(inv_T(read_pose_csv(p).T)[0, :3, 3], [-100, -200, -300])
