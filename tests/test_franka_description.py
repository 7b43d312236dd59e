"""`lasercal export --format franka`: franka_description's own xacro, processed as ROS processes it
(xacrodoc, ``hand:=false``) with the exported kinematics.yaml in place, puts ``<id>_link8`` where the
calibrated model puts its flange -- checked by pinocchio's forward kinematics of the resulting URDF, which
shares no code with lasercal -- and the unmodified files reproduce lasercal's nominal Panda and FR3.

The description is ../shared/data/franka_description (PROVENANCE.md); the tests skip where it is absent.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.control.tools import flange
from lasercal.solver.formats.export import export, franka_frames
from lasercal.solver.formats.franka import franka_origins, not_carried, to_franka
from lasercal.solver.formats.robots import load_model
from lasercal.solver.kinematics.ik import tool_frames
from lasercal.solver.kinematics.poe import adjoint, exp6

FD = Path(__file__).resolve().parents[2] / "shared" / "data" / "franka_description"
TOL_MM = 1e-6
needs_fd = pytest.mark.skipif(not (FD / "robots" / "fer" / "fer.urdf.xacro").is_file(), reason=f"no {FD}")


def _rot(rng, s):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(rng.normal(0.0, s, 3)).as_matrix()


def _pose(R, p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def every_deviation_model():
    """A Panda with every deviation a calibration finds: the base frame away from joint 1 (3 mm, 5 mrad),
    each axis tilted (20 mrad) and shifted (2 mm), a zero offset of every joint (up to 20 mrad), a tilted
    laser, a target, a joint compliance and a sensor transform (seeded)."""
    nominal = load_model("panda")
    rng = np.random.default_rng(40)
    B = _pose(_rot(rng, 0.005), rng.normal(0.0, 3.0, 3))
    screws = []
    for S, F in zip(nominal.screws, franka_frames()):
        w, p = S[:3], F[:3, 3]  # unit axis and Franka's joint frame origin on it
        w, p = _rot(rng, 0.02) @ w, p + rng.normal(0.0, 2.0, 3)  # tilted about its own point, shifted
        w, p = B[:3, :3] @ w, B[:3, :3] @ p + B[:3, 3]
        screws.append(np.r_[w, -np.cross(w, p)])
    screws = np.array(screws)
    laser = B @ _pose(_rot(rng, 0.02), nominal.aperture + rng.normal(0.0, 2.0, 3))
    target = B @ _pose(np.eye(3), nominal.aperture + [30.0, -20.0, 40.0])
    for i, d in enumerate(rng.uniform(-0.02, 0.02, 7)):  # the zero offsets: e^[S_i] d moves all after joint i
        E = exp6(screws[i] * d)
        screws[i + 1 :] = screws[i + 1 :] @ adjoint(E).T
        laser, target = E @ laser, E @ target
    return nominal.replace(
        name="panda_every_deviation",
        screws=screws,
        laser_dir=laser[:3, :3] @ nominal.laser_dir,
        aperture=laser[:3, 3],
        targets={"T1": target[:3, 3]},
        extensions={"joint_compliance": {"units": "rad/Nm", "joints": [2, 4], "c": [-2e-5, -1e-5]}},
        sensor_pose=_pose(_rot(rng, 0.3), [1500.0, 200.0, -300.0]),
        nominal="panda",
    )


def xacro_urdf(tmp_path: Path, robot_id: str, kinematics: str | None = None) -> str:
    """The URDF franka_description's xacro builds for ``robot_id`` (hand:=false), with ``kinematics`` (the
    text of a kinematics.yaml) in place of its own: a copy of the description in tmp_path, never the
    original."""
    xacrodoc = pytest.importorskip("xacrodoc")
    from xacrodoc import packages

    root = tmp_path / f"franka_description_{robot_id}"
    shutil.copytree(FD, root)
    if kinematics is not None:
        (root / "robots" / robot_id / "kinematics.yaml").write_text(kinematics)
    packages.update_package_cache({"franka_description": str(root)})
    doc = xacrodoc.XacroDoc.from_file(
        str(root / "robots" / robot_id / f"{robot_id}.urdf.xacro"), subargs={"hand": "false"}
    )
    return doc.to_urdf_string()


def pin_link_poses(urdf: str, link: str, q: np.ndarray) -> np.ndarray:
    """The link's poses (m, 4, 4) mm in the URDF's root frame at q (m, 7) rad, by pinocchio."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromXML(urdf)
    assert model.nq == 7, model.nq
    data = model.createData()
    fid = model.getFrameId(link)
    assert fid < model.nframes, f"no frame {link}"
    out = []
    for qi in q:
        pin.framesForwardKinematics(model, data, qi)
        out.append(np.array(data.oMf[fid].homogeneous))
    out = np.array(out)
    out[:, :3, 3] *= 1000.0
    return out


def model_flange(model, q: np.ndarray) -> np.ndarray:
    """The calibrated model's flange (m, 4, 4) mm at q: its screws' product of exponentials (no effects)."""
    return tool_frames(model.screws, flange(model), q)[0]


def random_q(model, m: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(model.limits[:, 0], model.limits[:, 1], (m, model.n))


def largest_difference(A: np.ndarray, B: np.ndarray) -> tuple[float, float]:
    """Largest position difference (mm) and rotation difference (rad: the largest entry of R_A - R_B, the
    angle to first order without arccos's loss of digits near 0) of two stacks of poses."""
    dp = np.linalg.norm(A[:, :3, 3] - B[:, :3, 3], axis=1).max()
    return float(dp), float(np.abs(A[:, :3, :3] - B[:, :3, :3]).max())


@needs_fd
@pytest.mark.parametrize("name, robot_id", [("panda", "fer"), ("fr3", "fr3")])
def test_the_unmodified_description_is_lasercals_nominal_model(name, robot_id, tmp_path):
    model = load_model(name)
    q = random_q(model, 200, 1)
    dp, dr = largest_difference(pin_link_poses(xacro_urdf(tmp_path, robot_id), f"{robot_id}_link8", q),
                                model_flange(model, q))  # fmt: skip
    print(f"{name}: unmodified {robot_id} description vs lasercal's nominal: {dp:.3g} mm, {dr:.3g} rad")
    assert dp < TOL_MM and dr < 1e-9


@needs_fd
@pytest.mark.parametrize("name, robot_id", [("panda", "fer"), ("fr3", "fr3"), ("fr3", "fp3")])
def test_the_nominal_model_writes_frankas_own_file_value_for_value(name, robot_id):
    ours = yaml.safe_load(to_franka(load_model(name), robot_id))
    assert ours == yaml.safe_load((FD / "robots" / robot_id / "kinematics.yaml").read_text())


MODELS = {"every deviation": every_deviation_model, "thesis": lambda: load_model("panda_thesis_identified")}


@needs_fd
@pytest.mark.parametrize(
    "name, robot_id", [("every deviation", r) for r in ("fer", "fr3", "fr3v2", "fp3")] + [("thesis", "fer")]
)
def test_the_exported_kinematics_puts_link8_on_the_calibrated_flange(name, robot_id, tmp_path):
    model = MODELS[name]()
    urdf = xacro_urdf(tmp_path, robot_id, to_franka(model, robot_id))
    q = random_q(model, 300, 2)
    got = pin_link_poses(urdf, f"{robot_id}_link8", q)
    dp, dr = largest_difference(got, model_flange(model, q))
    print(f"{robot_id}: {name} model vs its exported kinematics.yaml: {dp:.3g} mm, {dr:.3g} rad")
    assert dp < TOL_MM and dr < 1e-9
    # the same flange as `export --format urdf` puts at panda_link8 (what an outside check compares)
    ours = pin_link_poses(export(model, "urdf"), "panda_link8", q)
    assert largest_difference(got, ours)[0] < TOL_MM
    # the deviations are real: the nominal description misses the calibrated flange by millimetres
    nominal = pin_link_poses(xacro_urdf(tmp_path / "nominal", robot_id), f"{robot_id}_link8", q)
    assert largest_difference(nominal, got)[0] > 5.0


def test_a_zero_offset_turns_its_own_link_and_leaves_the_next_origin():
    """A zero offset d of joint 3 alone: joint 3's origin turns by d about its own z (its link turns with
    it), the origins after it stay Franka's -- but joint 7's, which turns the flange back about its own axis
    (by -d about the base's z): the flange's turn about its axis is unobservable and stays the nominal's (at
    q = 0 axes 3 and 7 are parallel, so d about axis 3 is a shift of axis 7 and a turn of the flange about
    it)."""
    nominal = load_model("panda")
    d = 0.03
    E = exp6(nominal.screws[2] * d)
    screws = np.array(nominal.screws)
    screws[3:] = screws[3:] @ adjoint(E).T
    shifted = nominal.replace(screws=screws, aperture=(E @ np.r_[nominal.aperture, 1.0])[:3],
                              laser_dir=E[:3, :3] @ nominal.laser_dir)  # fmt: skip
    O0, O1 = franka_origins(nominal), franka_origins(shifted)

    def Rz(a):
        c, s = np.cos(a), np.sin(a)
        return _pose(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]), np.zeros(3))

    assert np.abs(O1[2] - O0[2] @ Rz(d)).max() < 1e-12
    assert np.abs(O1[6] - O0[6] @ Rz(d)).max() < 1e-12  # z7 points down: -d about the base's z
    others = [0, 1, 3, 4, 5, 7]
    assert np.abs(O1[others] - O0[others]).max() < 1e-9


def test_what_the_file_cannot_carry_is_said_with_its_size():
    notes = not_carried(every_deviation_model())
    text = "\n".join(notes)
    assert "laser" in text and "aperture at (" in text and "deg from its z axis" in text
    assert "target 'T1' at (" in text
    assert "joint_compliance of joint(s) 2, 4" in text and "mm at the flange" in text
    assert "sensor's transform" in text
    # the compliance's size is measured, not a constant: twice the compliance, twice the flange's shift
    model = every_deviation_model()

    def size(scale):
        ext = {"joint_compliance": {"units": "rad/Nm", "joints": [2, 4], "c": [-2e-5 * scale, -1e-5 * scale]}}
        s = next(s for s in not_carried(model.replace(extensions=ext)) if "compliance" in s)
        return float(s.split("mrad of joint angle, ")[1].split(" mm")[0])

    assert size(1) > 0.1 and abs(size(2) / size(1) - 2.0) < 0.01


def test_the_command_writes_the_file_and_warns(tmp_path, capsys):
    model = every_deviation_model()
    model.save(tmp_path / "model.yaml")
    out = tmp_path / "kinematics.yaml"
    assert main(["export", str(tmp_path / "model.yaml"), "--format", "franka", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    d = yaml.safe_load(out.read_text())
    assert list(d) == [f"joint{i}" for i in range(1, 9)]
    assert all(set(v["kinematic"]) == {"x", "y", "z", "roll", "pitch", "yaw"} for v in d.values())
    assert all(isinstance(x, int | float) for v in d.values() for x in v["kinematic"].values())
    text = out.read_text()
    assert text.startswith("# lasercal export of panda_every_deviation") and "x, y, z in m" in text
    warned = [ln for ln in err.splitlines() if ln.startswith("lasercal: warning: not in kinematics.yaml: ")]
    assert len(warned) == 4, err  # laser, target, compliance, sensor
    # the file written from the model file is the one written from the model (the file keeps 12 digits)
    saved = load_model(tmp_path / "model.yaml")
    origins = franka_origins(saved)
    for i, v in enumerate(d.values()):
        assert abs(v["kinematic"]["z"] * 1000.0 - origins[i][2, 3]) < 1e-9


@needs_fd
def test_the_fr3s_gravity_model_is_franka_descriptions(tmp_path):
    # the built-in fr3's links (masses and centres of mass, mm in the base frame at q = 0) give the gravity
    # torques pinocchio computes from franka_description's URDF inertials (the FR3 has no Gaz et al. table)
    pin = pytest.importorskip("pinocchio")
    from lasercal.solver.kinematics.gravity import gravity_torques

    model = load_model("fr3")
    urdf = pin.buildModelFromXML(xacro_urdf(tmp_path, "fr3"))
    data = urdf.createData()
    q = random_q(model, 50, 4)
    tau = np.array([pin.computeGeneralizedGravity(urdf, data, qi) for qi in q])
    assert np.abs(gravity_torques(model, q) - tau).max() < 2e-3 * np.abs(tau).max()  # COMs rounded to um
