"""validate (and configurations) command a model's robot effects as correct does: a model that holds a
compliance aims its true pose, not the geometric one (issue 46: a MuJoCo world's compliance, found by solve,
validated worse than the geometry alone, 0.771 against 0.315 mm, because the effects were left out).

The truth here shares no code with the solver (issue 51): the true beam is computed in this file from the
model file's numbers alone -- forward kinematics by scipy's matrix exponential of each joint's twist, the
gravity torques as a Jacobian-transpose sum over the links' masses and centres of mass, the links'
deflection as the fixed point q_link = q + c tau(q_link) -- and not by the solver's ``poe``, ``gravity``,
``elastic`` or ``effects`` modules (which the fake backend and validate use)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import yaml
from scipy.linalg import expm

from lasercal.collector.cli.main import main
from lasercal.solver.formats.robots import load_model

PANDA = Path(__file__).resolve().parents[1] / "data" / "robots" / "panda.yaml"

P4 = np.array([441.0, 160.0, -8.0])  # the thesis layout's validation point, base frame, mm
G = 9.81  # m/s^2


def hat(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def twist(S):
    """The 4 x 4 matrix [S] of a screw (omega, v)."""
    out = np.zeros((4, 4))
    out[:3, :3], out[:3, 3] = hat(S[:3]), S[3:]
    return out


def frames(screws, q):
    """T_0..T_n: T_k = expm([S_1] q_1) ... expm([S_k] q_k), by scipy's matrix exponential."""
    out = [np.eye(4)]
    for S, qi in zip(screws, q):
        out.append(out[-1] @ expm(twist(S) * qi))
    return out


def torques(robot: dict, q):
    """Gravity torques (n,) Nm holding the arm still, tau_j = dV/dq_j = sum_{i >= j} m_i g z . (w_j x (c_i -
    p_j)), with w_j, p_j joint j's axis and a point on it carried by T_(j-1), c_i link i's centre of mass
    carried by T_i (base z up; mm -> m)."""
    S = robot["screws"]
    T = frames(S, q)
    tau = np.zeros(len(q))
    for j in range(len(q)):
        w0, v0 = S[j, :3], S[j, 3:]
        w = T[j][:3, :3] @ w0
        p = T[j][:3, :3] @ np.cross(w0, v0) + T[j][:3, 3]  # the axis' point nearest the origin, carried
        for i in range(j, len(q)):
            c = T[i + 1][:3, :3] @ robot["com"][i] + T[i + 1][:3, 3]
            tau[j] += robot["mass"][i] * G * np.cross(w, c - p)[2] / 1000.0
    return tau


def spot(robot: dict, link) -> np.ndarray:
    """Where the beam meets the plane z = P4's, mm (x, y), with the links at ``link`` (rad)."""
    T = frames(robot["screws"], link)[-1]
    a, d = T[:3, :3] @ robot["aperture"] + T[:3, 3], T[:3, :3] @ robot["laser_dir"]
    return (a + (P4[2] - a[2]) / d[2] * d)[:2]


def true_spot(robot: dict, q) -> np.ndarray:
    """The true spot (x, y) mm with the encoders at q: the links bent to the fixed point q_link = q + c
    tau(q_link) of the robot's own weight (its own links)."""
    link = np.array(q, float)
    for _ in range(50):  # c tau is a few mrad; each step shrinks the change ~100-fold
        link, prev = q + robot["c"] * torques(robot, link), link
        if np.abs(link - prev).max() < 1e-15:
            break
    return spot(robot, link)


def read_robot(path) -> dict:
    """The model file's numbers, read as YAML here (not through the solver's loader)."""
    doc = yaml.safe_load(open(path).read())
    links = doc["links"]
    n = len(doc["joints"])
    c = np.zeros(n)
    jc = (doc.get("extensions") or {}).get("joint_compliance")
    if jc:
        c[np.array(jc["joints"]) - 1] = jc["c"]
    return {
        "screws": np.array([[*j["omega"], *j["v"]] for j in doc["joints"]], float),
        "aperture": np.array(doc["laser"]["M"], float),  # the laser's aperture at q = 0
        "laser_dir": np.array(doc["laser"]["v"], float),  # its prismatic screw (0, v): the beam
        "mass": np.array([lk["mass"] for lk in links], float),
        "com": np.array([lk["com"] for lk in links], float),
        "c": c,
    }


def rows(path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def test_a_model_with_a_compliance_is_validated_with_it(tmp_path):
    truth = tmp_path / "T.yaml"  # the thesis's Panda with a joint-2 compliance: about 5 mm at P4
    t = load_model("panda_thesis_identified")
    ext = {"joint_compliance": {"units": "rad/Nm", "joints": [2], "c": [3e-4]}}
    t.replace(name="compliant", nominal="panda", extensions=ext).save(truth)
    t.replace(name="rigid", nominal="panda", extensions={}).save(tmp_path / "rigid.yaml")
    real = read_robot(truth)
    assert real["c"][1] == 3e-4 and len(real["mass"]) == len(real["screws"]) == 7
    nominal = read_robot(PANDA)
    off, said = {}, {}
    for model in ("T", "rigid"):
        run = ["validate", str(tmp_path / f"{model}.yaml"), "--backend", "fake", "--truth", str(truth)]
        run += ["--layout", "thesis", "--point", "P4", "-n", "6", "-o", str(tmp_path / model)]
        assert main(run) == 0
        planned = tmp_path / f"{model}.csv"
        assert main(["configurations", str(tmp_path / f"{model}.yaml"), "--layout", "thesis", "--point",
                     "P4", "-n", "6", "-o", str(planned)]) == 0  # fmt: skip
        commanded = np.loadtxt(planned, delimiter=",", skiprows=2)[:, 1:8]
        done = rows(tmp_path / model / "validation.csv")
        q = np.array([[float(r[f"q{k}"]) for k in range(1, 8)] for r in done])
        # the arm went where configurations says validate commands (the fake arm's repeatability: ~1e-4 rad)
        assert np.abs(q - commanded[[int(r["index"]) for r in done]]).max() < 1e-3
        # where the commands put the true beam, by this file's physics
        off[model] = np.array([np.linalg.norm(true_spot(real, qc) - P4[:2]) for qc in commanded])
        # where the model itself says they put it: the links at q + c tau(q), tau at the commanded angles
        # from the nominal panda's gravity model (docs/use.md: correct's model, the fit's torques)
        said[model] = np.array([np.linalg.norm(spot(real, qc + real["c"] * torques(nominal, qc)) - P4[:2])
                                for qc in commanded])  # fmt: skip
        # validate's photos measure, at the angles read, the spot this file's truth puts there: within the
        # fake camera's error (benchmarks/bench_camera_sigma_clean.py: the largest of 2,000 photos 0.11 mm;
        # 0.15 as tests/test_fake_truth_effects.py; the photo's noise is keyed by q's bits: a fresh draw)
        seen = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in done])
        want = np.array([true_spot(real, qi) for qi in q])
        assert np.abs(seen - want).max() < 0.15, (model, seen - want)
    # validate commands the compliance exactly as the model states it: under it, the beam meets P4 (the
    # fixed point's and the aiming's tolerance, deterministic: no noise enters the commands)
    assert said["T"].max() < 1e-6, said
    # the physical truth (the spring bent by the torques at the bent pose, the truth's own links) lands
    # within the model's first-order approximation of it: deterministic, 0.042 mm at most on these 6
    # configurations; the geometry alone misses by the joint-2 bend (0.6-3.9 mm, mean 1.98)
    assert off["T"].max() < 0.05 < 1.0 < off["rigid"].mean(), off
