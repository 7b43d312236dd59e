"""URDF ``<mimic>``: the one-source case of a coupling (q_j = c q_k + b), against an independent FK."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.urdf import load_urdf
from lasercal.solver.kinematics.poe import poe_chain

# (name, type, origin xyz m, origin rpy rad, axis, mimic (joint, multiplier, offset) or None)
JOINTS = [
    ("j1", "revolute", (0, 0, 0.3), (0, 0, 0), (0, 0, 1), None),
    ("j2", "revolute", (0.05, 0, 0.2), (0.3, 0, 0), (0, 1, 0), None),
    ("j3", "revolute", (0.4, 0, 0), (0, 0.2, 0), (0, 1, 0), ("j2", -0.5, 0.2)),  # a parallelogram's joint
    ("slide", "prismatic", (0.1, 0, 0), (0, 0, 0), (1, 0, 0), ("j3", 0.03, 0.01)),  # m per rad, m
    ("j4", "revolute", (0.3, 0.02, 0), (0, 0, 0.4), (1, 0, 0), None),
]
TIP = ((0.1, 0, 0.05), (0.1, 0.2, 0.3))


def urdf(joints=JOINTS) -> str:
    links = "".join(f'<link name="l{i}"/>' for i in range(len(joints) + 2))
    body = []
    for i, (nm, kind, xyz, rpy, axis, mimic) in enumerate(joints):
        m = f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]}" offset="{mimic[2]}"/>' if mimic else ""
        body.append(
            f'<joint name="{nm}" type="{kind}"><parent link="l{i}"/><child link="l{i + 1}"/>'
            f'<origin xyz="{" ".join(map(str, xyz))}" rpy="{" ".join(map(str, rpy))}"/>'
            f'<axis xyz="{" ".join(map(str, axis))}"/>'
            f'<limit lower="-3" upper="3" effort="1" velocity="1"/>{m}</joint>'
        )
    n = len(joints)
    body.append(
        f'<joint name="tip" type="fixed"><parent link="l{n}"/><child link="l{n + 1}"/>'
        f'<origin xyz="{" ".join(map(str, TIP[0]))}" rpy="{" ".join(map(str, TIP[1]))}"/></joint>'
    )
    return f'<robot name="mimic">{links}{"".join(body)}</robot>'


def transform(xyz, rpy, axis=None, kind="fixed", q=0.0) -> np.ndarray:
    """A URDF joint's transform: its origin (m), then its motion about/along its axis."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T[:3, 3] = xyz
    M = np.eye(4)
    if kind == "revolute":
        M[:3, :3] = Rotation.from_rotvec(np.asarray(axis, float) * q).as_matrix()
    elif kind == "prismatic":
        M[:3, 3] = np.asarray(axis, float) * q
    return T @ M


def reference_tip(qc: dict) -> np.ndarray:
    """The tip frame (mm) by composing the URDF's transforms, each mimic joint at c q_k + b (SI units)."""
    q, T = dict(qc), np.eye(4)
    for nm, kind, xyz, rpy, axis, mimic in JOINTS:
        if mimic:
            q[nm] = mimic[1] * q[mimic[0]] + mimic[2]
        T = T @ transform(xyz, rpy, axis, kind, q[nm])
    T = T @ transform(*TIP)
    T[:3, 3] *= 1000.0
    return T


def test_mimic_joints_are_driven_by_their_source(tmp_path):
    (tmp_path / "m.urdf").write_text(urdf())
    model = load_urdf(tmp_path / "m.urdf")
    assert model.commanded == ("j1", "j2", "j4") and model.n == 5
    rng = np.random.default_rng(3)
    qc = rng.uniform(-2, 2, (10, 3))
    E = poe_chain(model.screws, model.described(qc))[:, -1] @ model.ee_pose
    for got, row in zip(E, qc):
        want = reference_tip(dict(zip(("j1", "j2", "j4"), row)))
        assert np.abs(got[:3, 3] - want[:3, 3]).max() < 1e-9  # mm
        assert np.abs(got[:3, :3] - want[:3, :3]).max() < 1e-12
    assert model.coupling[3, 1] == pytest.approx(-0.5 * 0.03 * 1000)  # slide (mm) from j2 through j3


def test_a_mimic_of_a_joint_off_the_chain_is_named(tmp_path):
    joints = JOINTS[:2] + [JOINTS[2][:5] + (("nowhere", 1.0, 0.0),)]
    (tmp_path / "m.urdf").write_text(urdf(joints))
    with pytest.raises(FormatError, match="mimics 'nowhere'") as e:
        load_urdf(tmp_path / "m.urdf")
    assert "j3.mimic" in str(e.value)
