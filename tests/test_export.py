"""lasercal export: the URDF and the DH table move the beam exactly as the POE model does."""

from __future__ import annotations

import csv
import io
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from lasercal.collector.cli.main import main
from lasercal.collector.hardware.fake import perturbed_model
from lasercal.solver.formats.export import FRANKA_ORIGINS, export, kinematic_frames, to_dh, to_urdf
from lasercal.solver.formats.robots import load_model, model_from_dict
from lasercal.solver.formats.urdf import EE_LINK, load_urdf
from lasercal.solver.kinematics.laser import beam
from lasercal.solver.kinematics.minimal import normalise_screw
from lasercal.solver.kinematics.poe import poe_chain, space_jacobian


def rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


def homogeneous(R=None, p=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def urdf_fk(text: str, q: np.ndarray) -> dict:
    """Every link's pose (mm) from the URDF text alone: chain the origins, rotate revolute joints about their
    axes (a chain with fixed leaves: the laser, {E})."""
    root = ET.fromstring(text)
    joints: dict = {}
    for j in root.findall("joint"):
        joints.setdefault(j.find("parent").get("link"), []).append(j)
    children = {j.find("child").get("link") for j in root.findall("joint")}
    link = next(lk.get("name") for lk in root.findall("link") if lk.get("name") not in children)
    poses, stack, k = {link: np.eye(4)}, [link], 0
    while stack:
        parent = stack.pop()
        for j in joints.get(parent, []):
            o = j.find("origin")
            xyz = 1000.0 * np.array(o.get("xyz").split(), float)
            r, p, y = np.array(o.get("rpy").split(), float)
            T = poses[parent] @ homogeneous(rot("z", y) @ rot("y", p) @ rot("x", r), xyz)
            if j.get("type") == "revolute":
                axis = np.array(j.find("axis").get("xyz").split(), float)
                w = axis / np.linalg.norm(axis)
                K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
                T = T @ homogeneous(np.eye(3) + np.sin(q[k]) * K + (1 - np.cos(q[k])) * K @ K)
                poses[f"axis{k}"] = (T[:3, :3] @ w, T[:3, 3])
                k += 1
            child = j.find("child").get("link")
            poses[child] = T
            stack.append(child)
    return poses


def dh_fk(text: str, q: np.ndarray) -> np.ndarray:
    """The laser frame (mm) from the DH table alone."""
    d = yaml.safe_load(text)

    def pose(p):
        r, pi, y = p["rpy"]
        return homogeneous(rot("z", y) @ rot("y", pi) @ rot("x", r), p["xyz"])

    T = pose(d["base"])
    for row, qi in zip(d["joints"] + [d["flange"]], list(q) + [0.0]):  # the flange: a fixed row
        T = (
            T
            @ homogeneous(rot("x", row["alpha"]))
            @ homogeneous(p=[row["a"], 0, 0])
            @ homogeneous(rot("z", row["theta"] + qi))
            @ homogeneous(p=[0, 0, row["d"]])
        )
    return T @ pose(d["tool"])


def random_q(model, k: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(model.limits[:, 0], model.limits[:, 1], (k, model.n))


MODELS = {
    "thesis-identified panda": lambda: load_model("panda_thesis_identified"),
    "perturbed panda": lambda: perturbed_model(load_model("panda"), seed=3, rotation=1e-2, offset=3.0),
    "fr3": lambda: load_model("fr3"),
    "puma560 (generic frames)": lambda: load_model("puma560_thesis_actual"),
}


@pytest.mark.parametrize("name", MODELS)
def test_urdf_forward_kinematics_equals_poe(name):
    model = MODELS[name]()
    text = to_urdf(model)
    prefix = "fr3_" if name == "fr3" else "panda_" if "panda" in name else ""
    for q in random_q(model, 25, 1):
        poses = urdf_fk(text, q)
        b = beam(model.screws, model.laser_dir, model.aperture, q[None])
        laser = poses[f"{prefix}laser"]
        assert np.abs(laser[:3, 3] - b.aperture[0]).max() < 1e-9  # mm
        assert np.abs(laser[:3, 2] - b.direction[0]).max() < 1e-12
        J = space_jacobian(model.screws, poe_chain(model.screws, q[None]))[
            0
        ]  # (6, n): each joint's screw at q
        for i in range(model.n):
            w, p = poses[f"axis{i}"]
            assert np.abs(w - J[:3, i]).max() < 1e-12
            assert np.abs(-np.cross(w, p) - J[3:, i]).max() < 1e-9  # the URDF's axis lies on the POE line


def test_urdf_of_the_nominal_panda_is_frankas():
    root = ET.fromstring(to_urdf(load_model("panda")))
    joints = [j for j in root.findall("joint") if j.get("type") == "revolute"]
    assert [j.get("name") for j in joints] == [f"panda_joint{i}" for i in range(1, 8)]
    assert [j.find("child").get("link") for j in joints] == [f"panda_link{i}" for i in range(1, 8)]
    for j, (xyz, rpy) in zip(joints, FRANKA_ORIGINS):
        o = j.find("origin")
        assert np.allclose(np.array(o.get("xyz").split(), float), xyz, atol=1e-15)
        assert np.allclose(np.array(o.get("rpy").split(), float), rpy, atol=1e-15)
        assert j.find("axis").get("xyz") == "0 0 1"
    lim = joints[3].find("limit")
    assert (float(lim.get("lower")), float(lim.get("upper")), float(lim.get("effort"))) == (
        -3.0718,
        -0.0698,
        87.0,
    )
    flange = next(j for j in root.findall("joint") if j.get("name") == "panda_joint8")
    assert flange.get("type") == "fixed" and np.allclose(
        np.array(flange.find("origin").get("xyz").split(), float), [0, 0, 0.107]
    )


def test_every_source_file_an_export_names_exists():
    """A header that says where its equations live points at a file that is there (it once named
    solver/export.py, gone since the solver's floors)."""
    root = Path(__file__).resolve().parents[1]
    heads = [to_dh(load_model("panda")).splitlines()[0], to_urdf(load_model("panda"))[:2000]]
    named = [p for h in heads for p in re.findall(r"\b((?:solver|collector|vision)/[\w/]+\.py)", h)]
    assert named and all((root / p).is_file() for p in named), named


def test_dh_of_the_nominal_panda_is_frankas_table():
    # Franka's published modified DH table (a, d in m; alpha in rad), independent of the URDF origins above.
    a = [0, 0, 0, 0.0825, -0.0825, 0, 0.088]
    d = [0.333, 0, 0.316, 0, 0.384, 0, 0]
    alpha = [0, -np.pi / 2, np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, np.pi / 2]
    t = yaml.safe_load(to_dh(load_model("panda")))
    assert np.allclose([j["a"] for j in t["joints"]], 1000 * np.array(a), atol=1e-9)
    assert np.allclose([j["d"] for j in t["joints"]], 1000 * np.array(d), atol=1e-9)
    assert np.allclose([j["alpha"] for j in t["joints"]], alpha, atol=1e-12)
    assert np.allclose([j["theta"] for j in t["joints"]], 0, atol=1e-12)
    assert np.allclose(t["base"]["xyz"] + t["base"]["rpy"], 0, atol=1e-12)
    flange = t["flange"]  # Franka's panda_joint8: 107 mm along joint 7's axis
    assert flange["name"] == "panda_joint8"
    assert np.allclose([flange[k] for k in ("alpha", "a", "theta", "d")], [0, 0, 0, 107], atol=1e-9)
    # the aperture, 208 mm below joint 7's frame along its axis: 101 mm beyond the flange
    assert np.allclose(t["tool"]["xyz"], [0, 0, 101], atol=1e-9)


@pytest.mark.parametrize("name", MODELS)
def test_dh_forward_kinematics_equals_poe(name):
    model = MODELS[name]()
    text = to_dh(model)
    table = yaml.safe_load(text)
    assert np.allclose([j["omega"] + j["v"] for j in table["joints"]], model.screws, atol=1e-12)
    for q in random_q(model, 25, 2):
        T = dh_fk(text, q)
        b = beam(model.screws, model.laser_dir, model.aperture, q[None])
        assert np.abs(T[:3, 3] - b.aperture[0]).max() < 1e-8  # mm (the table is printed to 12 decimals)
        assert np.abs(T[:3, 2] - b.direction[0]).max() < 1e-11


def test_yaml_passthrough_and_extensions(tmp_path):
    model = load_model("panda_thesis_identified").replace(
        extensions={"joint_compliance": {"units": "rad/Nm", "joints": [2], "c": [1.2e-4]}}
    )
    again = model_from_dict(yaml.safe_load(export(model, "yaml")))
    assert np.allclose(again.screws, model.screws, atol=1e-12) and again.extensions == model.extensions
    assert "joint_compliance" in to_urdf(model).split("<robot")[0]  # said, in a comment, before the robot
    assert yaml.safe_load(to_dh(model))["extensions"] == model.extensions


def test_export_cli(tmp_path, capsys):
    assert main(["export", "panda_thesis_identified", "--format", "urdf"]) == 0
    assert ET.fromstring(capsys.readouterr().out).get("name") == "panda"
    out = tmp_path / "panda.dh.yaml"
    assert main(["export", "panda", "--format", "dh", "-o", str(out)]) == 0
    assert yaml.safe_load(out.read_text())["format"] == "lasercal-dh/1"
    capsys.readouterr()
    assert main(["export", str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lasercal export: error:") and "missing.yaml" in err[0]


def _pinocchio_frames(text: str, names: list, q: np.ndarray, prismatic=None) -> dict:
    """Poses (4, 4, mm) of named frames of a URDF, by pinocchio (an independent URDF library); q in rad and
    mm (prismatic joints); continuous joints take (cos, sin)."""
    pin = pytest.importorskip("pinocchio")
    robot = pin.buildModelFromXML(text)
    data = robot.createData()
    cfg = np.zeros(robot.nq)
    for j, jm in enumerate(robot.joints[1:]):
        if jm.nq == 2:
            cfg[jm.idx_q : jm.idx_q + 2] = np.cos(q[j]), np.sin(q[j])
        else:
            cfg[jm.idx_q] = q[j] / (1000.0 if prismatic is not None and prismatic[j] else 1.0)
    pin.framesForwardKinematics(robot, data, cfg)
    out = {}
    for nm in names:
        T = data.oMf[robot.getFrameId(nm)].homogeneous.copy()
        T[:3, 3] *= 1000.0
        out[nm] = T
    return out


def _laser_directions(model) -> dict:
    """Beam directions at q = 0 that stress the laser frame: along the flange's x (and -x, y), along the
    last axis, horizontal, up, and random ones."""
    F = kinematic_frames(model)
    last = F.flange if F.flange is not None else F.joints[-1]
    rng = np.random.default_rng(7)
    rand = rng.normal(size=(3, 3))
    dirs = {
        "flange x": last[:3, 0],
        "flange -x": -last[:3, 0],
        "flange y": last[:3, 1],
        "last axis": last[:3, 2],
    }
    dirs |= {"horizontal": np.array([0.6, 0.8, 0.0]), "up": np.array([0.0, 0.0, 1.0])}
    dirs |= {f"random {k}": v / np.linalg.norm(v) for k, v in enumerate(rand)}
    return dirs


@pytest.mark.parametrize("name", ["perturbed panda", "puma560 (generic frames)"])
def test_urdf_any_laser_direction_by_pinocchio(name):
    base = MODELS[name]()
    prefix = "panda_" if "panda" in name else ""
    for label, vp in _laser_directions(base).items():
        model = base.replace(laser_dir=vp)
        text = to_urdf(model)  # the flange-x beam crashed here (a frame from a cross product with x)
        F = kinematic_frames(model)
        assert np.allclose(F.laser[:3, 2], vp, atol=1e-12) and np.allclose(F.laser[:3, 3], model.aperture)
        for q in random_q(model, 10, 3):
            got = _pinocchio_frames(text, [f"{prefix}laser"], q)[f"{prefix}laser"]
            want = poe_chain(model.screws, q[None])[0, -1] @ F.laser  # lasercal's laser frame at q
            b = beam(model.screws, model.laser_dir, model.aperture, q[None])
            assert np.abs(got[:3, 3] - want[:3, 3]).max() < 1e-6, label  # mm
            assert np.abs(got[:3, :3] - want[:3, :3]).max() < 1e-9, label
            assert (
                np.abs(got[:3, 3] - b.aperture[0]).max() < 1e-6
                and np.abs(got[:3, 2] - b.direction[0]).max() < 1e-9
            )


def test_urdf_names_the_full_pose_frame():
    model = MODELS["perturbed panda"]()
    ee = np.eye(4)
    ee[:3, :3] = Rotation.from_rotvec([0.3, -0.2, 2.0]).as_matrix()
    ee[:3, 3] = [95.0, 12.0, 760.0]
    text = to_urdf(model.replace(ee_pose=ee))
    root = ET.fromstring(text)
    joint = next(j for j in root.findall("joint") if j.find("child").get("link") == EE_LINK)
    assert joint.get("name") == f"{EE_LINK}_joint" and joint.get("type") == "fixed"
    assert joint.find("parent").get("link") == "panda_link8"  # on the flange, beside panda_laser
    assert EE_LINK not in to_urdf(model)  # only a full-pose model has {E}
    for q in random_q(model, 10, 4):
        got = _pinocchio_frames(text, [EE_LINK], q)[EE_LINK]
        want = poe_chain(model.screws, q[None])[0, -1] @ ee  # {E}(q) = E(q) M_E
        assert (
            np.abs(got[:3, 3] - want[:3, 3]).max() < 1e-6 and np.abs(got[:3, :3] - want[:3, :3]).max() < 1e-9
        )


@pytest.mark.parametrize("name", ["perturbed panda", "puma560 (generic frames)"])
def test_dh_flange_row_any_laser_direction(name):
    base = MODELS[name]()
    for label, vp in _laser_directions(base).items():
        model = base.replace(laser_dir=vp)
        text = to_dh(model)
        row = yaml.safe_load(text)["flange"]
        assert row["alpha"] == row["a"] == row["theta"] == 0.0  # a slide along the last axis
        for q in random_q(model, 5, 5):
            T = dh_fk(text, q)
            b = beam(model.screws, model.laser_dir, model.aperture, q[None])
            assert np.abs(T[:3, 3] - b.aperture[0]).max() < 1e-8, label
            assert np.abs(T[:3, 2] - b.direction[0]).max() < 1e-11, label


def test_predict_flags_beams_that_miss_the_plane(tmp_path, capsys):
    model = load_model("panda")
    q = random_q(model, 40, 6)
    b = beam(model.screws, model.laser_dir, model.aperture, q)
    cfg = tmp_path / "configs.csv"
    cfg.write_text("q1,q2,q3,q4,q5,q6,q7\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in q))
    capsys.readouterr()
    assert main(["predict", "panda", str(cfg), "--plane-z", "0"]) == 0
    cap = capsys.readouterr()
    rows = list(csv.DictReader(io.StringIO(cap.out)))
    length = -b.aperture[:, 2] / b.direction[:, 2]  # independent: t with a_z + t d_z = 0
    away = length < 0
    assert 0 < away.sum() < len(q)  # random poses point both ways
    assert [r["valid"] for r in rows] == ["false" if a else "true" for a in away]
    for r, a, t, ap, d in zip(rows, away, length, b.aperture, b.direction):
        assert np.isclose(float(r["laser_length"]), t, atol=1e-5)
        if a:
            assert r["spot_x"] == r["spot_y"] == ""  # never a spot behind the laser
        else:
            assert np.allclose([float(r["spot_x"]), float(r["spot_y"])], (ap + t * d)[:2], atol=1e-5)
    assert f"{away.sum()} of {len(q)} configurations have no spot" in cap.err


@pytest.mark.parametrize("name", ["ur5", "rail_ur5"])
def test_urdf_from_a_urdf_names_the_full_pose_frame(name):
    """A model from a URDF (no targets) exports its {E} (the tip link's frame) as lasercal_ee."""
    nominal = load_urdf(Path(__file__).parent / "data" / f"{name}.urdf")
    rng = np.random.default_rng(8)
    noise = rng.normal(0, [1e-3] * 3 + [0.5] * 3, nominal.screws.shape) * ~nominal.prismatic[:, None]
    screws = np.array([normalise_screw(S)[0] for S in nominal.screws + noise])  # revolute axes moved
    model = nominal.replace(screws=screws, targets={})
    text = export(model, "urdf")
    assert "lasercal_tool" not in text
    for q in rng.uniform(-2, 2, (10, model.n)) * np.where(model.prismatic, 100, 1):
        got = _pinocchio_frames(text, [EE_LINK], q, model.prismatic)[EE_LINK]
        want = poe_chain(model.screws, q[None])[0, -1] @ model.ee_pose
        assert (
            np.abs(got[:3, 3] - want[:3, 3]).max() < 1e-6 and np.abs(got[:3, :3] - want[:3, :3]).max() < 1e-9
        )
