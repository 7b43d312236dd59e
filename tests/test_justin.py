"""The built-in robot ``justin`` (a tree with a coupled torso) against DLR's facts, and ``import-justin``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.justin import read_dlr_measurements
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.position import target_anchor_heights, target_frames
from lasercal.solver.kinematics.gravity import gravity_torques
from lasercal.solver.kinematics.minimal import anchor_heights
from lasercal.solver.kinematics.tree import branch_groups, tree_frames
from tests.conftest import craig_row

JUSTIN = Path(__file__).resolve().parents[2] / "shared" / "data" / "justin"
needs_data = pytest.mark.skipif(
    not (JUSTIN / "robot-facts.yaml").is_file(),
    reason=f"Justin data not found at {JUSTIN} (see PROVENANCE.md there)",
)


def _craig(d, theta_deg, r, alpha_deg, q):
    """A facts file's DH row (metres, degrees) at q (rad): Rx(alpha) Tx(r) Rz(theta + q) Tz(d) in mm."""
    return craig_row(np.radians(alpha_deg), 1000 * r, np.radians(theta_deg) + q, 1000 * d)


def _static(a):
    """A static frame: metres -> mm, its printed rotation (0.866 for cos 30 deg) as the nearest rotation."""
    T = np.array(a, dtype=float)
    U, _, Vt = np.linalg.svd(T[:3, :3])
    T[:3, :3] = U @ Vt
    T[:3, 3] *= 1000
    return T


def facts_tcp(facts: dict, qc: np.ndarray, arm: str) -> np.ndarray:
    """Each arm's TCP (4, 4) mm at commanded q (19,): the facts' DH rows, static frames and coupling."""
    fr, dh = facts["frames"], facts["dh"]
    qt = [qc[0], qc[1], qc[2], -(qc[1] + qc[2])]
    T = _static(fr["torso_base"])
    for row, qi in zip(dh["torso"], qt):
        T = T @ _craig(*row, qi)
    T = T @ _static(fr[f"{arm}_arm_base"])
    qa = qc[3:10] if arm == "right" else qc[10:17]
    for row, qi in zip(dh[f"{arm}_arm"], qa):
        T = T @ _craig(*row, qi)
    return T @ _static(fr["tcp"])


@needs_data
def test_justin_forward_kinematics_matches_the_facts_craig_dh_table():
    facts = yaml.safe_load((JUSTIN / "robot-facts.yaml").read_text())
    model = load_model("justin")
    rng = np.random.default_rng(7)
    qc = rng.uniform(-np.pi, np.pi, (20, 19))
    q = model.described(qc)
    for arm in ("right", "left"):
        E = target_frames(model, q, np.full(len(q), arm, dtype=object))
        tcp0 = facts_tcp(facts, np.zeros(19), arm)
        want = np.array([facts_tcp(facts, qi, arm) for qi in qc])
        got = E @ tcp0
        assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-9  # mm
        assert np.abs(got[:, :3, :3] - want[:, :3, :3]).max() < 1e-12


@needs_data
def test_justin_gravity_torques_are_the_gradient_of_its_potential_energy():
    model = load_model("justin")
    q = model.described(np.random.default_rng(3).uniform(-2, 2, (4, 19)))
    mass = np.array([lk.mass for lk in model.links])
    com = np.array([lk.com for lk in model.links])

    def potential(q):  # J: 9.81 m/s^2 times the masses' heights (mm -> m)
        T, _ = tree_frames(model, q)
        z = np.einsum("mbj,bj->mb", T[:, :, 2, :3], com) + T[:, :, 2, 3]
        return 9.81e-3 * z @ mass

    h = 1e-6
    fd = np.stack([(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(model.n)], axis=1)
    tau = gravity_torques(model, q)
    assert np.abs(tau - fd).max() < 1e-5 * np.abs(tau).max()
    assert abs(mass.sum() - 51.451) < 1e-9  # 42.451 kg CAD + 2 hands + the head


@needs_data
def test_import_justin_writes_a_position_session_of_every_record(tmp_path):
    out = tmp_path / "s"
    assert main(["import-justin", str(JUSTIN / "measurements.csv"), "-o", str(out)]) == 0
    index, qc, markers, _ = read_dlr_measurements(JUSTIN / "measurements.csv")
    s = load_session(out)
    assert s.m == 2 * len(index) == 700
    assert list(s.point[:2]) == ["right", "left"]
    assert np.allclose(s.target[0::2], markers[:, 0]) and np.allclose(s.target[1::2], markers[:, 1])
    assert np.allclose(s.q[0::2], s.robot.described(qc))
    assert s.robot.target_links == {"right": "right_hand", "left": "left_hand"}


def test_a_malformed_record_is_named_by_its_line(tmp_path):
    good = ",joints,markers\n0,[" + " ".join(["0.1"] * 19) + '],"[[-1.8  2.2  1.5]\n [-3.0  1.6  1.8]]"\n'
    p = tmp_path / "m.csv"
    p.write_text(good + "1,[" + " ".join(["0.1"] * 18) + '],"[[-1.8  2.2  1.5]\n [-3.0  1.6  1.8]]"\n')
    with pytest.raises(FormatError, match=r"line 4.*joints|joints.*line 4") as e:
        read_dlr_measurements(p)
    assert "19" in str(e.value)
    p.write_text(good + "2,[" + " ".join(["0.1"] * 19) + '],"[[-1.8  2.2  1.5]]"\n')
    with pytest.raises(FormatError, match="markers"):
        read_dlr_measurements(p)
    p.write_text(good)
    index, q, mk, lines = read_dlr_measurements(p)
    assert lines.tolist() == [2] and np.allclose(mk[0, 0], [-1800, 2200, 1500])


def test_tree_anchor_heights_are_each_branchs_serial_heights():
    """The prior's anchor heights on a tree: along each branch, as for the serial arm that branch is (its
    target the tool); the torso's last joint, parent of both arms, between the two arms' feet."""
    model = load_model("justin")
    tree = target_anchor_heights(model, model.targets)
    real = model.real
    for arm in ("right", "left"):
        ((_, path),) = branch_groups(model, [arm])
        chain = path[real[path]]  # the branch's joints that turn, base to hand: a serial arm
        serial = anchor_heights(model.screws[chain], model.targets[arm])
        names = [model.joint_names[j] for j in chain]
        own = [k for k, nm in enumerate(names) if nm.startswith(arm)] + [0, 1, 2]
        assert np.allclose(tree[chain[own]], serial[own], atol=1e-9)
        heights = {nm: h for nm, h in zip(names, serial)}
        if arm == "right":
            right_torso_4 = heights["torso_4"]
    assert tree[model.joint_names.index("torso_4")] == pytest.approx((right_torso_4 + heights["torso_4"]) / 2)
    # the arms mirror each other: a joint's anchor is as far along its axis on either side
    for k in range(1, 8):
        r, lf = model.joint_names.index(f"right_{k}"), model.joint_names.index(f"left_{k}")
        assert abs(abs(tree[r]) - abs(tree[lf])) < 1e-6
