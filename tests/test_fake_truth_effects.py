"""Issue 45 item 1: the fake robot carries every effect a ``--truth`` model file holds -- its encoders report
q while its links stand where the effects put them -- or refuses the file naming what it cannot simulate.

The truths are computed here independently of the fake arm: the bent pose by a plain fixed-point loop on the
truth's gravity torques, the drift from the session's logged clock."""

from __future__ import annotations

import io
import shutil

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.collector.hardware import make_robot
from lasercal.collector.sessions.settings import capture_settings
from lasercal.collector.sessions.spotcam import capture_camera
from lasercal.collector.sessions.start import CaptureGuide, start_capture
from lasercal.collector.worlds.fakeworld import World
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.gravity import gravity_torques

TRUTH = load_model("panda_thesis_identified")
NOMINAL = load_model("panda")
# The fake camera in a clean world: benchmarks/bench_camera_sigma.py both 200 7 3 (1,000 photos),
# 40-photo sessions resampled 200,000 times (--bounds 40): the 0.1 % and 99.9 % quantiles of the z-score RMS;
# the largest error (mm) from the photos' tail, the bootstrap 95 % upper limit of its 99.9 % session quantile
# (``largest_bound``; tests/test_collector_franky_sim.py says why not resampled).
BENT_PHOTOS = 40
CLEAN_Z_RMS_40 = (0.816, 1.483)
CLEAN_LARGEST_ERROR_40 = 0.1368
THESIS = load_layout(builtin_dir("layouts") / "thesis.yaml")
C2 = -1.5e-4  # rad/Nm on joint 2: a sag of a few mrad under the Panda's own weight


def compliant(c=C2, joint=2, **more):
    """The thesis's Panda with a compliance at ``joint`` (and any further extensions)."""
    ext = {"joint_compliance": {"units": "rad/Nm", "joints": [joint], "c": [c]}, **more}
    return TRUTH.replace(extensions=ext, name="compliant")


def bent(q, c=C2, joint=2):
    """Where the links of the compliant truth stand when its encoders read q (n,): q + c tau(link) e_joint,
    iterated on the truth's own gravity torques (independent of the fake arm's code)."""
    link = np.array(q, dtype=float)
    for _ in range(30):
        link = q + c * gravity_torques(TRUTH, link[None])[0] * (np.arange(7) == joint - 1)
    return link


def fake(truth, per_point=0, **cfg):
    settings = {"backend": "fake", "truth": "panda_thesis_identified", "aim_noise": 0.0, "seed": 2, **cfg}
    robot = make_robot(settings, NOMINAL, THESIS, per_point, truth=truth)
    robot.connect()
    return robot


def test_compliance_moves_the_recorded_angles_by_c_times_the_true_torque():
    """The operator brings the links to the same pose with or without the compliance (their draws are
    keyed); the encoders then read that pose minus c tau(link) at joint 2, and the torque sensor the true
    torques there (noise 0.05 Nm); the bent arm's beam is where the operator aimed it."""
    plain, bending = fake(TRUTH, per_point=2), fake(compliant(), per_point=2)
    for robot in (plain, bending):
        robot.prompt_point("P2", None, 1)
        robot.clock.sleep(20.0)  # transit and release jiggle over
    s0, s1 = plain.read(), bending.read()
    link = bending.true_q()
    np.testing.assert_allclose(link, s0.q, rtol=0, atol=1e-12)  # the same pose of the links
    tau = gravity_torques(TRUTH, link[None])[0]
    expected = np.where(np.arange(7) == 1, C2 * tau, 0.0)
    assert abs(expected[1]) > 2e-3  # milliradians: an effect, not round-off
    np.testing.assert_allclose(link - s1.q, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s1.tau, tau, atol=0.25)  # 5 sigma of the sensor noise
    np.testing.assert_allclose(
        link, bent(s1.q), rtol=0, atol=1e-12
    )  # the links are where the encoders say they bend
    # the bent beam lands on the point; the encoders' pose, read as rigid, misses it by millimetres
    spot = predict_spots(TRUTH, link[None], THESIS.plane_z)[0][0]
    rigid = predict_spots(TRUTH, s1.q[None], THESIS.plane_z)[0][0]
    np.testing.assert_allclose(spot[:2], THESIS.points["P2"][:2], rtol=0, atol=1e-5)
    assert np.linalg.norm(rigid - spot) > 1.0


def test_a_commanded_pose_bends_and_the_spot_moves_by_the_analytic_amount():
    """A position-controlled move puts the encoders at q; the links sag to the fixed point q + c tau(link)."""
    q = aim(TRUTH, THESIS.points["P1"], 3, np.random.default_rng(5))
    for qk in q:
        robot = fake(compliant())
        robot.move_to(qk)
        robot.clock.sleep(20.0)  # the release jiggle over
        np.testing.assert_allclose(robot.read().q, qk, rtol=0, atol=1e-12)
        np.testing.assert_allclose(robot.true_q(), bent(qk), rtol=0, atol=1e-12)
        moved = robot.true_spot(THESIS.plane_z)[0] - predict_spots(TRUTH, qk[None], THESIS.plane_z)[0][0]
        expected = (
            predict_spots(TRUTH, bent(qk)[None], THESIS.plane_z)[0][0]
            - predict_spots(TRUTH, qk[None], THESIS.plane_z)[0][0]
        )
        assert np.linalg.norm(expected) > 1.0
        np.testing.assert_allclose(moved, expected, rtol=0, atol=1e-6)


def test_the_fake_camera_photographs_the_spot_of_the_truly_bent_arm(sheet):
    """The sheet camera's measured spot is where the bent arm's beam meets the sheet, not the rigid one's, as
    near as its stated sigma says. Over BENT_PHOTOS photos, the z-score RMS (error / stated sigma, both axes)
    lies within the 0.1 % and 99.9 % quantiles of 40-photo sessions resampled 200,000 times from the clean
    world's 1,000 photos (benchmarks/bench_camera_sigma.py both 200 7 3, then --bounds 40): a sigma 1.5x too
    large or too small leaves it (checked by scaling it), and the rigid arm's spots (0.2-0.7 mm off) leave it
    far."""
    layout = load_layout(sheet)
    cfg = {"backend": "fake", "truth": "panda_thesis_identified", "aim_noise": 0.0, "seed": 1}
    robot = make_robot(cfg, NOMINAL, layout.in_base(), truth=compliant())
    camera, measure = capture_camera("fake", cfg, robot, layout, sheet, World())
    robot.connect()
    target = layout.in_base().points["P3"] + np.r_[10.0, 10.0, 0.0]
    z, z_rigid, worst = [], [], 0.0
    for k, q in enumerate(aim(TRUTH, target, BENT_PHOTOS, np.random.default_rng(3))):
        robot.move_to(q)
        robot.clock.sleep(20.0)
        m = measure(camera.photo(), f"bent-{k}")
        on_sheet = layout.sheet.from_base(predict_spots(TRUTH, bent(q)[None], layout.plane_z)[0])[0]
        rigid = layout.sheet.from_base(predict_spots(TRUTH, q[None], layout.plane_z)[0])[0]
        z.append((m.xy - on_sheet) / m.sigma)
        z_rigid.append((m.xy - rigid) / m.sigma)
        worst = max(worst, float(np.abs(m.xy - on_sheet).max()))
    z_rms = float(np.sqrt(np.mean(np.square(z))))
    assert CLEAN_Z_RMS_40[0] < z_rms < CLEAN_Z_RMS_40[1], (z_rms, np.array(z))
    assert worst < CLEAN_LARGEST_ERROR_40, worst
    assert (
        np.sqrt(np.mean(np.square(z_rigid))) > 2 * CLEAN_Z_RMS_40[1]
    )  # the rigid arm's spots: 0.2-0.7 mm off


def test_a_drift_runs_on_the_sessions_clock_across_a_resume(tmp_path):
    """drift at joint 1: the links stand at q + r t with t captures.csv's own clock. The operator brings the
    links to the same poses as in a session without the drift (keyed draws), so the encoders read r t less
    (less the drift while the arm settles);
    a session cut after 3 captures and resumed (the fake clock restarts at 0) logs the same rows -- with the
    drift's clock restarting at the resume, its rows would be r t_cut off."""
    r = 2e-4  # rad/s
    truth = tmp_path / "drift.yaml"
    d = yaml.safe_load((builtin_dir("robots") / "panda_thesis_identified.yaml").read_text())
    d["extensions"] = {"drift": {"units": "rad/s", "joints": [1], "r": [r]}}
    truth.write_text(yaml.safe_dump(d))
    given = {"backend": "fake", "per_point": 2, "aim_noise": 0.0, "seed": 3}
    guide = CaptureGuide(auto=True, coach=False)
    layout = str(builtin_dir("layouts") / "thesis.yaml")
    for name, extra in (("ref", {"truth": str(truth)}), ("rigid", {})):
        start_capture(capture_settings({**given, **extra}, layout, str(tmp_path / name)), guide).run(
            io.StringIO()
        )
    ref, rigid = load_session(tmp_path / "ref"), load_session(tmp_path / "rigid")
    np.testing.assert_array_equal(ref.t, rigid.t)
    assert r * ref.t[3] > 2e-3  # the drift at the cut: milliradians
    np.testing.assert_array_equal(ref.q[:, 1:], rigid.q[:, 1:])
    # the encoders read r t less, but for the drift while the arm settles after the operator let go (0.5-5 s)
    settling = (ref.q[:, 0] - rigid.q[:, 0] + r * ref.t) / r
    assert np.all((settling > 0.5) & (settling < 5.0)), settling
    shutil.copytree(tmp_path / "ref", tmp_path / "s")
    lines = (tmp_path / "s" / "captures.csv").read_text().splitlines(keepends=True)
    (tmp_path / "s" / "captures.csv").write_text("".join(lines[:4]))  # header + 3 captures: a kill
    start_capture(capture_settings({}, resume=str(tmp_path / "s")), guide).run(io.StringIO())
    s = load_session(tmp_path / "s")
    assert list(s.point) == list(ref.point) and s.m == 6
    np.testing.assert_allclose(
        s.q + np.outer(r * s.t, np.eye(7)[0]), ref.q + np.outer(r * ref.t, np.eye(7)[0]), rtol=0, atol=1e-9
    )


def test_a_point_offset_moves_where_the_operator_aims_on_a_measured_layout():
    """reference_point_offset at P2 (base-frame layout): the point truly lies (dx, dy) off; the operator aims
    the true beam there."""
    off = {"point": "P2", "units": "mm", "dx": [3.0], "dy": [-2.0]}
    robot = fake(TRUTH.replace(extensions={"reference_point_offset": off}), per_point=1)
    robot.prompt_point("P2", None, 0)
    robot.clock.sleep(20.0)
    spot = robot.true_spot(THESIS.plane_z)[0]
    np.testing.assert_allclose(spot[:2], THESIS.points["P2"][:2] + [3.0, -2.0], rtol=0, atol=1e-5)


def _truth_file(tmp_path, ext) -> str:
    d = yaml.safe_load((builtin_dir("robots") / "panda_thesis_identified.yaml").read_text())
    d["extensions"] = ext
    path = tmp_path / "T.yaml"
    path.write_text(yaml.safe_dump(d))
    return str(path)


@pytest.mark.parametrize(
    "ext, layout, field",
    [
        (
            {"lateral_compliance": {"units": "rad/Nm", "joints": [2], "c": [1e-4]}},
            "thesis",
            "lateral_compliance",
        ),
        (
            {"joint_compliance": {"units": "rad/Nm", "joints": [2], "c": ["3e-4x"]}},
            "thesis",
            "joint_compliance",
        ),
        ({"joint_compliance": {"units": "rad/Nm", "joints": [9], "c": [3e-4]}}, "thesis", "joint_compliance"),
        ({"reference_point_offset": {"point": "P2", "dx": [1.0]}}, "thesis", "reference_point_offset"),
        (
            {"reference_point_offset": {"point": "P9", "dx": [1.0], "dy": [0.0]}},
            "thesis",
            "reference_point_offset",
        ),
        (
            {"reference_point_offset": {"point": "P2", "dx": [1.0], "dy": [0.0]}},
            "sheet",
            "reference_point_offset",
        ),
        ({"joint_map": {"joints": [2], "step": 0.05, "start": [0.0]}}, "thesis", "joint_map"),
    ],
)
def test_a_truth_the_fake_arm_cannot_simulate_is_refused_naming_file_and_field(
    tmp_path, monkeypatch, capsys, sheet, ext, layout, field
):
    """Exit 2, at most 3 lines on stderr naming the truth's file and extensions.FIELD, no folder made."""
    monkeypatch.chdir(tmp_path)
    truth = _truth_file(tmp_path, ext)
    lay = str(sheet) if layout == "sheet" else layout
    args = ["capture", "--layout", lay, "--robot", "panda", "--backend", "fake", "--auto", "--per-point", "1"]
    code = main([*args, "--no-coach", "--truth", truth, "-o", "s"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "T.yaml" in err and f"extensions.{field}" in err, err
    assert len(err.strip().splitlines()) <= 3, err
    assert not (tmp_path / "s").exists()
