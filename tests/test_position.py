"""Position sessions on arms loaded from URDF: recovery against simulated truth, URDF out checked by
pinocchio (an independent URDF implementation), and bad input."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.analysis.simulate import random_configs, simulate_positions
from lasercal.solver.analysis.stats import cross_validate
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.positions import position_meta, write_position_session
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.formats.tolerances import robot_tolerances
from lasercal.solver.formats.urdf import calibrated_urdf, load_urdf
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.position import sensor_points
from tests.conftest import angle_error_positions, perturbed

DATA = Path(__file__).parent / "data"


def session(tmp, name, m, noise, seed, urdf_ref=None):
    nominal = load_urdf(DATA / f"{name}.urdf")
    rng = np.random.default_rng(seed)
    truth = perturbed(nominal, rng)
    names = np.tile(np.array(list(truth.targets), dtype=object), m)
    q = np.repeat(random_configs(nominal, m, rng), 3, axis=0)
    y = simulate_positions(truth, q, names, noise, rng)
    write_position_session(
        tmp, position_meta(urdf_ref or str(DATA / f"{name}.urdf"), truth.targets), q, y, names
    )
    return load_session(tmp), truth


def heldout_error(model, truth, seed=9, m=200):
    rng = np.random.default_rng(seed)
    q = random_configs(truth, m, rng)
    names = np.tile(np.array(list(truth.targets), dtype=object), m)
    q = np.repeat(q, 3, axis=0)
    return np.linalg.norm(sensor_points(model, q, names) - sensor_points(truth, q, names), axis=1)


@pytest.mark.parametrize("name", ["ur5", "arm7", "rail_ur5"])
def test_exact_recovery_without_noise(tmp_path, name):
    s, truth = session(tmp_path, name, 40, 0.0, 1)
    # exact data: as the noise prior vanishes, the prior's weight sigma^2 / s^2 does too (eqs. P2-P3)
    ident = fit(dataclasses.replace(s, tolerances=robot_tolerances(s.robot).with_noise("position", 1e-9)))
    assert ident.converged and not ident.identifiability.unidentifiable
    assert heldout_error(ident.model, truth).max() < 1e-6


@pytest.mark.parametrize("name", ["ur5", "arm7"])
def test_noise_floor(tmp_path, name):
    """Held-out prediction error (cross-validated, against the measured positions) is the sensor noise:
    E|n| of 3-D Gaussian noise is 1.596 sigma, plus the small estimation error."""
    sigma = 0.02
    s, truth = session(tmp_path, name, 60, sigma, 2)
    ident = fit(s)
    cv = cross_validate(s, k=5)
    # bounds from the figures' spread over 30 seeds per robot (benchmarks/bench_noise_floor.py, seeds
    # 2-31): the CV mean 1.56-1.82 sigma (ur5 mean 1.660 sd 0.051, arm7 1.667 sd 0.052; the old upper bound
    # 1.75 failed 3 of 60 draws, a fourth at 1.750), the truth RMS 0.33-0.59 sigma (0.442 sd 0.052, 0.479 sd
    # 0.056): the bounds are the normal fits' 0.05 % / 99.95 % quantiles (CV, two-sided) and 99.9 %
    # quantile (truth), of the worse robot
    assert 1.48 * sigma < cv.errors.mean() < 1.85 * sigma
    assert cv.nominal_errors.mean() > 20 * sigma  # the perturbation is far above the noise
    assert np.sqrt(np.mean(heldout_error(ident.model, truth) ** 2)) < 0.66 * sigma


def _pin_fk(urdf: Path, q: np.ndarray, frame: str, prismatic: np.ndarray) -> np.ndarray:
    """Frame position (mm) by pinocchio; continuous joints take (cos, sin)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid = model.getFrameId(frame)
    out = []
    for qi in q:
        cfg = np.zeros(model.nq)
        for j, jm in enumerate(model.joints[1:]):
            if jm.nq == 2:
                cfg[jm.idx_q : jm.idx_q + 2] = np.cos(qi[j]), np.sin(qi[j])
            else:
                cfg[jm.idx_q] = qi[j] / (1000.0 if prismatic[j] else 1.0)  # mm -> m
        pin.framesForwardKinematics(model, data, cfg)
        out.append(1000.0 * data.oMf[fid].translation)
    return np.array(out)


@pytest.mark.parametrize("name", ["ur5", "rail_ur5"])
def test_calibrated_urdf_round_trip(tmp_path, name):
    """The exported URDF, read by pinocchio, puts every target where lasercal's calibrated model does."""
    s, truth = session(tmp_path / "s", name, 30, 0.01, 3)
    ident = fit(s)
    out = tmp_path / "cal.urdf"
    out.write_text(calibrated_urdf(ident.model))
    q = random_configs(truth, 25, np.random.default_rng(4))
    X = ident.model.sensor_pose
    for nm in ident.model.targets:
        ours = sensor_points(ident.model, q, np.full(len(q), nm, dtype=object))
        theirs = _pin_fk(out, q, f"lasercal_{nm}", ident.model.prismatic) @ X[:3, :3].T + X[:3, 3]
        assert np.abs(ours - theirs).max() < 1e-6
    text = out.read_text()
    nominal_text = (DATA / f"{name}.urdf").read_text()
    for kept in ('mass value="8.393"', "meshes/missing_forearm.stl", 'lower="-6.283185307179586"'):
        assert kept in nominal_text and kept in text  # inertias, meshes and limits kept


def test_model_yaml_round_trip(tmp_path):
    """An identified position model saved and reloaded predicts the same and still exports its URDF."""
    s, _ = session(tmp_path / "s", "rail_ur5", 20, 0.0, 5)
    m = fit(s).model
    m.save(tmp_path / "m.yaml")
    r = load_model(tmp_path / "m.yaml")
    q = random_configs(r, 10, np.random.default_rng(0))
    nm = np.full(10, "T2", dtype=object)
    assert np.abs(sensor_points(r, q, nm) - sensor_points(m, q, nm)).max() < 1e-8
    assert r.prismatic[0] and r.urdf == m.urdf and "lasercal_T2" in calibrated_urdf(r)


def test_cli_simulate_solve_predict_export(tmp_path, capsys):
    urdf = str(DATA / "arm7.urdf")
    S, M = tmp_path / "S", tmp_path / "m.yaml"
    assert (
        main(["simulate", urdf, "--measurement", "position", "--configs", "30", "--noise", "0", "-o", str(S)])
        == 0
    )
    assert main(["solve", str(S), "-o", str(M), "--folds", "3"]) == 0
    cfg = tmp_path / "c.csv"
    cfg.write_text("q1,q2,q3,q4,q5,q6,q7,target\n0,0,0,-1,0,1.5,0,T2\n0.1,0.2,0,-1.5,0,2,0,T1\n")
    capsys.readouterr()
    assert main(["predict", str(M), str(cfg)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].endswith("target,x,y,z") and len(lines) == 3 and lines[1].split(",")[7] == "T2"
    model = load_model(M)
    q = np.array([[0, 0, 0, -1, 0, 1.5, 0]])
    assert np.allclose(
        [float(v) for v in lines[1].split(",")[-3:]], sensor_points(model, q, ["T2"])[0], atol=1e-5
    )
    cfg.write_text("q1,q2,q3,q4,q5,q6,q7\n0,0,0,-1,0,1.5,0\n")
    assert main(["predict", str(M), str(cfg)]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == 1 + len(model.targets)
    assert (
        main(
            [
                "export",
                str(M),
                "--format",
                "urdf",
                "-o",
                str(tmp_path / "c.urdf"),
                "--sensor-output",
                str(tmp_path / "s.urdf"),
            ]
        )
        == 0
    )
    assert (
        "lasercal_T1" in (tmp_path / "c.urdf").read_text()
        and "sensor_to_base" in (tmp_path / "s.urdf").read_text()
    )


# ----------------------------------------------------------------------------- bad input
BRANCHED = """<robot name="b"><link name="base"/><link name="a"/><link name="b"/>
<joint name="ja" type="revolute"><parent link="base"/><child link="a"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<joint name="jb" type="revolute"><parent link="base"/><child link="b"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


def test_urdf_not_a_chain(tmp_path):
    p = tmp_path / "b.urdf"
    p.write_text(BRANCHED)
    with pytest.raises(FormatError, match=r"b\.urdf, field 'tip_link': the tree below 'base' branches"):
        load_urdf(p)
    with pytest.raises(FormatError, match=r"tip_link 'a' is not below base_link 'b'"):
        load_urdf(p, "b", "a")
    assert load_urdf(p, tip_link="a").n == 1


def test_missing_mesh_and_continuous_joint_are_stated():
    notes = " ".join(load_urdf(DATA / "ur5.urdf").notes)
    assert "mesh 'meshes/missing_forearm.stl' not found: ignored" in notes
    assert "continuous joint 'joint6' has no limits" in notes


def test_positions_in_metres_refused(tmp_path, capsys):
    s, _ = session(tmp_path / "s", "ur5", 15, 0.0, 6)
    text = (tmp_path / "s" / "captures.csv").read_text().splitlines()
    head, rows = text[0], [r.split(",") for r in text[1:]]
    for r in rows:
        r[-3:] = [repr(float(v) / 1000) for v in r[-3:]]
    (tmp_path / "s" / "captures.csv").write_text("\n".join([head] + [",".join(r) for r in rows]) + "\n")
    assert main(["solve", str(tmp_path / "s"), "-o", str(tmp_path / "m.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "captures.csv" in err and "look like metres" in err


def test_sensor_file_row_count(tmp_path, capsys):
    s, _ = session(tmp_path / "s", "ur5", 10, 0.0, 7)
    lines = (tmp_path / "s" / "captures.csv").read_text().splitlines()
    (tmp_path / "s" / "tracker.csv").write_text(
        "\n".join(["target,x,y,z"] + [",".join(r.split(",")[-4:]) for r in lines[1:-1]]) + "\n"
    )
    meta = yaml.safe_load((tmp_path / "s" / "session.yaml").read_text())
    meta["positions"] = "tracker.csv"
    (tmp_path / "s" / "session.yaml").write_text(yaml.safe_dump(meta))
    assert main(["solve", str(tmp_path / "s"), "-o", str(tmp_path / "m.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        len(err.splitlines()) == 1
        and "tracker.csv, field 'rows': 29 sensor rows but captures.csv has 30" in err
    )


# ----------------------------------------------------------------------------- --robot on the command line
def test_robot_option_replaces_the_session_robot(tmp_path, capsys, monkeypatch):
    """solve/diagnose --robot: a URDF path from the working folder in place of the session's (here gone);
    --base-link picks the UR5 out of rail+UR5, whose arm is the same UR5 on a carriage."""
    _, truth = session(tmp_path / "S", "ur5", 20, 0.0, 8)
    meta = yaml.safe_load((tmp_path / "S" / "session.yaml").read_text())
    meta["robot"] = "gone.urdf"
    (tmp_path / "S" / "session.yaml").write_text(yaml.safe_dump(meta))
    monkeypatch.chdir(tmp_path)
    assert main(["solve", "S", "-o", "m.yaml"]) == 2
    assert "gone.urdf" in capsys.readouterr().err
    (tmp_path / "arm.urdf").write_text((DATA / "ur5.urdf").read_text())
    exact = ["--prior", "none"]  # exact data, recovered exactly by least squares
    assert main(["solve", "S", "-o", "m.yaml", "--robot", "arm.urdf", "--folds", "0"] + exact) == 0
    model = load_model("m.yaml")
    assert model.urdf["file"] == str(tmp_path / "arm.urdf")
    assert heldout_error(model, truth).max() < 1e-6
    rail = ["--robot", str(DATA / "rail_ur5.urdf"), "--folds", "0"]
    assert main(["solve", "S", "-o", "r.yaml"] + rail) == 2  # 7 joints: the session logs 6
    assert "missing column(s) q7" in capsys.readouterr().err
    assert main(["solve", "S", "-o", "r.yaml", "--base-link", "base_link"] + rail + exact) == 0
    model = load_model("r.yaml")
    assert model.n == 6 and model.urdf["base_link"] == "base_link" and model.urdf["tip_link"] == "flange"
    assert heldout_error(model, truth).max() < 1e-6
    capsys.readouterr()
    assert (
        main(
            ["diagnose", "S", "--bootstrap", "0", "--refits", "0", "--json"]
            + rail[:2]
            + ["--base-link", "base_link"]
        )
        == 0
    )
    assert json.loads(capsys.readouterr().out)["effect"] == "none"


def test_fullpose_takes_a_urdf_and_its_chain(tmp_path, capsys):
    fp, m = str(tmp_path / "fp.csv"), str(tmp_path / "m.yaml")
    rail = ["--robot", str(DATA / "rail_ur5.urdf")]
    sim = ["simulate-fullpose", "--configs", "10", "--angles", "4", "--noise", "0", "-o", fp]
    assert main(sim + rail + ["--base-link", "base_link"]) == 0
    assert main(["fullpose", fp, "-o", m] + rail) == 2
    assert "fp.csv" in capsys.readouterr().err  # 6 joint columns, 7 joints
    assert main(["fullpose", fp, "-o", m, "--base-link", "base_link"] + rail) == 0
    model = load_model(m)
    assert model.n == 6 and model.urdf["base_link"] == "base_link"
    assert model.identification["accuracy"]["after"]["position_mm"]["max"] < 1e-5  # no noise: exact


# ----------------------------------------------------------------------------- folds keep a pose's targets
def test_folds_keep_the_targets_of_one_configuration_together(tmp_path):
    """Three targets per pose, the later targets' joint readings jittered below the pose tolerance, and
    pose 0 visited again at the end: every pose's rows share a fold, and all k folds are used."""
    from dataclasses import replace

    from lasercal.solver.analysis.stats import POSE_TOL_RAD, grouped_folds

    s, _ = session(tmp_path, "ur5", 20, 0.0, 10)
    pose = np.arange(s.m) // 3  # the simulated poses (np.repeat by 3): independent of the grouping
    jitter = np.random.default_rng(0).uniform(-0.4, 0.4, s.q.shape) * POSE_TOL_RAD * (pose % 3 > 0)[:, None]
    q = np.vstack([s.q + jitter, s.q[:3]])
    pose = np.r_[pose, 0, 0, 0]
    idx = np.r_[np.arange(s.m), 0, 1, 2]
    s2 = replace(s.subset(idx), q=q)
    for seed in range(3):
        f = grouped_folds(s2, 5, seed)
        assert all(len(set(f[pose == p])) == 1 for p in range(20))
        assert set(f) == set(range(5)) and np.bincount(f).min() >= 9  # 4 poses per fold, 5 in one
    assert (
        len(set(grouped_folds(replace(s2, q=q + 3 * POSE_TOL_RAD * np.arange(len(q))[:, None]), 5)[:3])) > 1
    )


# ----------------------------------------------------------------------------- compliance without inertias
def _bare_ur5(tmp_path) -> Path:
    """The UR5 fixture with every <inertial> removed: no gravity model."""
    import re

    p = tmp_path / "ur5_bare.urdf"
    p.write_text(re.sub(r"\s*<inertial>.*?</inertial>", "", (DATA / "ur5.urdf").read_text(), flags=re.S))
    assert not load_model(p).links
    return p


# A UR5 joint is about 2e4 Nm/rad stiff (c = 5e-5 rad/Nm); a 5 kg payload at the wrist loads it with 5 x the
# torques of the 1 kg lumped load the simulation and the fit use, so the folded compliance is 2.5e-4.
SAG_C = 5 * 5e-5
SIGMA = 0.02  # mm per axis: held-out 3-D RMS at the noise floor is sqrt(3) sigma


@pytest.mark.parametrize("hidden", [True, False])
def test_joint_compliance_without_inertias_is_found_by_extend_auto(tmp_path, capsys, hidden):
    urdf = _bare_ur5(tmp_path)
    S, M = tmp_path / "S", tmp_path / "m.yaml"
    sim = ["simulate", str(urdf), "--measurement", "position", "--configs", "40", "--noise", str(SIGMA)]
    effect = ["--effect", "joint_compliance", "--effect-joints", "2,3", "--effect-size", str(SAG_C)]
    assert main(sim + (effect if hidden else []) + ["--seed", "1", "-o", str(S)]) == 0
    capsys.readouterr()
    assert main(["solve", str(S), "-o", str(M), "--extend", "auto", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["diagnosis"]
    floor = np.sqrt(3) * SIGMA
    held = d["acceptance"]["holdout_rms_mm"]
    assert (
        d["details"]["torques"] == "lumped load at the wrist centre"
        and d["acceptance"]["grouping"] == "by configuration"
    )
    model = load_model(M)
    if hidden:
        assert d["effect"] == "joint_compliance" and d["joints"] == [2, 3]
        assert held["geometric"] > 10 * floor and held["extended"] < 1.15 * floor
        c = model.extensions["joint_compliance"]["c"]
        assert np.allclose(c, SAG_C, rtol=0.02)
    else:
        assert d["effect"] == "none" and not model.extensions
        assert held["geometric"] < 1.15 * floor


def angle_error_session(folder: Path, amp: float, m: int, new: int, seed: int):
    """:func:`~tests.conftest.angle_error_positions` at ``m`` + ``new`` configurations: the first ``m``
    written to ``folder`` as a session, the ``new`` returned: q (3 new, 6) rad, names, positions mm."""
    truth, q, names, y = angle_error_positions(amp, m + new, seed, SIGMA)
    meta = position_meta(str(DATA / "ur5.urdf"), truth.targets)
    write_position_session(folder, meta, q[: 3 * m], y[: 3 * m], names[: 3 * m])
    return q[3 * m :], names[3 * m :], y[3 * m :]


def predicted_rms(model: Path, q, names, y, tmp_path) -> float:
    """``lasercal predict`` on the configurations: 3-D RMS to the measured positions, mm."""
    cfg, out = tmp_path / "cfg.csv", tmp_path / "out.csv"
    cfg.write_text(
        "q1,q2,q3,q4,q5,q6,target\n"
        + "".join(",".join(map(repr, r.tolist())) + f",{nm}\n" for r, nm in zip(q, names))
    )
    assert main(["predict", str(model), str(cfg), "-o", str(out), "--force"]) == 0
    a = np.genfromtxt(out, delimiter=",", names=True, dtype=None, encoding=None)
    return float(np.sqrt(np.mean(np.sum((np.c_[a["x"], a["y"], a["z"]] - y) ** 2, axis=1))))


def test_a_joint_angle_error_is_kept_as_a_joint_map_and_predict_applies_it(tmp_path, capsys):
    """A 1 mrad angle error on joint 2 (:func:`angle_error_session`), 60 configurations: ``--extend auto``
    keeps the joint error map by its cross-validation (held out 3x better with it), the model file carries
    it, and predict applies it: 20 new configurations are predicted to within 3x the noise floor (the
    geometry alone misses them by more)."""
    S, M = tmp_path / "S", tmp_path / "m.yaml"
    held = angle_error_session(S, 1e-3, 60, 20, 5)
    assert main(["solve", str(S), "-o", str(M), "--extend", "auto", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["diagnosis"]
    jm = d["acceptance"]["joint_map"]
    assert d["effect"].endswith("joint_map") and jm["accepted"]
    assert jm["holdout_rms_mm"]["with"] < jm["holdout_rms_mm"]["without"] / 3
    assert "joint_map" in load_model(M).extensions
    assert predicted_rms(M, *held, tmp_path) < 3 * np.sqrt(3) * SIGMA


def test_a_map_whose_fold_gains_scatter_is_kept_when_it_predicts_better(tmp_path, capsys):
    """An angle error of 0.05 mrad (seed 4; 200 configurations): the map's pooled held-out RMS is 6 % lower,
    one fold of five a loss (fold gains -2.6 to +12.7 %, so the 95 % interval of the gains reaches below
    0). Kept, as every extension is, by the pooled held-out RMS: fitted on the session it predicts 200 new
    configurations 8.8 % better than the geometry (truth; the acceptance rule's evidence, on sessions with
    and without a map and on Justin's records, is in docs/position.md)."""
    S, M, G = tmp_path / "S", tmp_path / "m.yaml", tmp_path / "geo.yaml"
    held = angle_error_session(S, 5e-5, 200, 200, 4)
    assert main(["solve", str(S), "-o", str(M), "--extend", "auto", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["diagnosis"]
    jm = d["acceptance"]["joint_map"]
    assert min(jm["gain_percent_folds"]) < 0 and jm["gain_percent_ci95"][0] < 0  # not "CI above 0"
    assert jm["accepted"] and set(load_model(M).extensions) == {"joint_map"}
    assert main(["solve", str(S), "-o", str(G), "--folds", "0"]) == 0
    assert predicted_rms(M, *held, tmp_path) < 0.95 * predicted_rms(G, *held, tmp_path)


# ----------------------------------------------------------------------------- predict reproduces the fit
def test_predicting_the_training_captures_gives_the_fit_rms_and_distinct_columns(tmp_path, capsys):
    """``predict`` on a model's own training captures gives the fit RMS ``solve`` reports (to the output's
    rounding), with a joint compliance whose torques are not logged: both take the nominal robot's gravity
    torques at the commanded poses (the calibrated geometry's, with a shoulder 4 mm off the nominal's,
    moved the predictions by ~1e-3 mm, as 3.764 vs 3.742 mm on Justin). The measured x, y, z carried from
    the input are ``measured_x, ...``; the predicted keep ``x, y, z`` (docs/formats.md)."""
    truth = tmp_path / "truth.urdf"
    truth.write_text((DATA / "ur5.urdf").read_text().replace('xyz="0 0 0.089159"', 'xyz="0.004 0 0.089159"'))
    S, M, out = tmp_path / "S", tmp_path / "m.yaml", tmp_path / "out.csv"
    sim = ["simulate", str(truth), "--robot", str(DATA / "ur5.urdf"), "--measurement", "position"]
    effect = ["--effect", "joint_compliance", "--effect-joints", "2,3", "--effect-size", "5e-4"]
    assert main(sim + effect + ["--configs", "20", "--noise", "0.05", "-o", str(S)]) == 0
    assert main(["solve", str(S), "-o", str(M), "--extend", "joint_compliance", "--folds", "0"]) == 0
    assert main(["predict", str(M), str(S / "captures.csv"), "-o", str(out)]) == 0
    capsys.readouterr()
    header = out.read_text().splitlines()[0].split(",")
    assert header[-6:] == ["measured_x", "measured_y", "measured_z", "x", "y", "z"]
    a = np.genfromtxt(out, delimiter=",", names=True, dtype=None, encoding=None)
    d = np.c_[[a[k] - a[f"measured_{k}"] for k in "xyz"]].T
    rms = np.sqrt((d**2).sum(axis=1).mean())
    model = load_model(M)
    assert model.extensions["joint_compliance"]["joints"] == [2, 3]
    assert rms == pytest.approx(model.identification["fit_rms_mm"], abs=2e-6)  # 6 decimals written
