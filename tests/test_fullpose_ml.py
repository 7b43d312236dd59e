"""Maximum-likelihood full pose from every circle point (issue 15, item 4) against simulated truth and the
Cramer-Rao bound; the sensor frame 2.5 m from the base and rotated."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lasercal.collector.cli.main import build_parser
from lasercal.solver.analysis.simulate import random_configs
from lasercal.solver.formats.robots import load_model
from lasercal.solver.identify.circlepoint import circle_point_pose
from lasercal.solver.identify.fullpose import default_target, simulate_circlepoint
from lasercal.solver.identify.fullpose_ml import (
    TARGET,
    calibrate_points,
    frame_crb,
    frame_error_norms,
    frame_model,
)
from lasercal.solver.kinematics.poe import fk

SENSOR = np.eye(4)
SENSOR[:3, :3] = Rotation.from_euler("xyz", [20, -30, 135], degrees=True).as_matrix()
SENSOR[:3, 3] = [1800.0, -1500.0, 900.0]  # 2.51 m from the base


@pytest.fixture(scope="module")
def arms():
    tru = load_model("panda_thesis_identified")
    tgt = default_target(tru)
    truth = tru.replace(sensor_pose=SENSOR, targets={TARGET: tgt})
    return load_model("panda"), tru, tgt, truth


def frames(model, q):
    return fk(model.screws, model.ee_pose, q)


def test_frame_is_the_circle_point_frame_and_recovered_exactly(arms):
    nom, tru, tgt, truth = arms
    d = simulate_circlepoint(tru, 12, 6, np.radians(20), 0.0, np.random.default_rng(1), tgt, SENSOR)
    E = frame_model(truth)
    # {E} keeps its meaning: without noise the paper's construction gives exactly the model's frame
    assert np.allclose(circle_point_pose(d.points), frames(E, d.q[:, 0]), atol=1e-8)
    cal = calibrate_points(nom, d, estimate=True)
    qe = random_configs(tru, 50, np.random.default_rng(2))
    dp, dr = frame_error_norms(frames(cal.model, qe), frames(E, qe))
    assert dp.max() < 1e-6 and dr.max() < 1e-9
    assert cal.fit.identifiability.rank == cal.fit.identifiability.n_params == 4 * 7 - 6 + 6 + 3


def test_ml_beats_circle_and_reaches_the_cramer_rao_bound(arms):
    nom, tru, tgt, truth = arms
    rng = np.random.default_rng(5)
    d = simulate_circlepoint(tru, 30, 6, np.radians(20), 0.05, rng, tgt, SENSOR)
    qe = random_configs(tru, 200, rng)
    cal = calibrate_points(nom, d, estimate=True)
    TE = frames(frame_model(truth), qe)
    ml = [np.sqrt(np.mean(e**2)) for e in frame_error_norms(frames(cal.model, qe), TE)]
    circ = [np.sqrt(np.mean(e**2)) for e in frame_error_norms(frames(cal.circle.model, qe), TE)]
    crb = frame_crb(truth, d.q.reshape(-1, 7), 0.05, qe)
    assert 0.7 < ml[0] / crb[0] < 1.3 and 0.7 < ml[1] / crb[1] < 1.3
    assert circ[0] > 1.5 * ml[0] and circ[1] > 1.5 * ml[1]
    assert abs(cal.fit.sigma_mm / 0.05 - 1) < 0.1  # the point residuals are the sensor noise


def run(argv):
    a = build_parser(argv[0]).parse_args(argv)
    return a.func(a)


def test_cli_default_is_maximum_likelihood(tmp_path, capsys):
    m, out = tmp_path / "m.csv", tmp_path / "id.yaml"
    sim = ["simulate-fullpose", "--robot", "panda_thesis_identified", "--configs", "15", "--noise", "0.01"]
    assert run(sim + ["--sensor", "1800", "-1500", "900", "20", "-30", "135", "-o", str(m)]) == 0
    assert "sensor frame ^S T_base" in m.read_text() and "wrote" in capsys.readouterr().out
    args = ["fullpose", str(m), "--robot", "panda", "--estimate-frames", "-o", str(out), "--json"]
    assert run(args) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["method"].startswith("fullpose-ml") and rep["points"] == 90 and rep["poses"] == 15
    assert rep["identifiability"]["rank"] == 31 and abs(rep["sigma_mm"] / 0.01 - 1) < 0.2
    E = load_model(out).ee_pose
    assert np.allclose(E[:3, :3].T @ E[:3, :3], np.eye(3), atol=1e-9)
    assert run(args + ["--method", "circle", "--force"]) == 0  # the model just written is replaced on purpose
    assert json.loads(capsys.readouterr().out)["method"].startswith("fullpose-poe")
