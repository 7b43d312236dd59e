"""lasercal export: the URDF and the DH table move the beam exactly as the POE model does."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.collector.hardware.fake import perturbed_model
from lasercal.solver.formats.export import FRANKA_ORIGINS, export, to_dh, to_urdf
from lasercal.solver.formats.robots import load_model, model_from_dict
from lasercal.solver.kinematics.laser import beam
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
    axes."""
    root = ET.fromstring(text)
    joints = {j.find("parent").get("link"): j for j in root.findall("joint")}
    children = {j.find("child").get("link") for j in root.findall("joint")}
    link = next(lk.get("name") for lk in root.findall("link") if lk.get("name") not in children)
    poses, T, k = {link: np.eye(4)}, np.eye(4), 0
    while link in joints:
        j = joints[link]
        o = j.find("origin")
        xyz = 1000.0 * np.array(o.get("xyz").split(), float)
        r, p, y = np.array(o.get("rpy").split(), float)
        T = T @ homogeneous(rot("z", y) @ rot("y", p) @ rot("x", r), xyz)
        if j.get("type") == "revolute":
            axis = np.array(j.find("axis").get("xyz").split(), float)
            w = axis / np.linalg.norm(axis)
            K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
            T = T @ homogeneous(np.eye(3) + np.sin(q[k]) * K + (1 - np.cos(q[k])) * K @ K)
            poses[f"axis{k}"] = (T[:3, :3] @ w, T[:3, 3])
            k += 1
        link = j.find("child").get("link")
        poses[link] = T
    return poses


def dh_fk(text: str, q: np.ndarray) -> np.ndarray:
    """The laser frame (mm) from the DH table alone."""
    d = yaml.safe_load(text)

    def pose(p):
        r, pi, y = p["rpy"]
        return homogeneous(rot("z", y) @ rot("y", pi) @ rot("x", r), p["xyz"])

    T = pose(d["base"])
    for row, qi in zip(d["joints"], q):
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
    assert np.allclose(
        t["tool"]["xyz"], [0, 0, 208], atol=1e-9
    )  # the aperture, 208 mm below joint 7's frame along its axis


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
    assert len(err) == 1 and err[0].startswith("lasercal: error:") and "missing.yaml" in err[0]
