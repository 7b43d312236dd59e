"""The capture session on the fake backend: calibration quality, standstill, checks, discards, disconnects."""

from __future__ import annotations

import io

import numpy as np
import pytest

from lasercal.collector.errors import RobotConnectionError
from lasercal.collector.hardware.base import FakeClock
from lasercal.collector.hardware.rangefinder import FakeRangefinder
from lasercal.collector.hardware.triggers import AutoTrigger, EnterTrigger
from lasercal.collector.sessions.capture import CaptureOptions, run_capture
from lasercal.collector.sessions.store import CaptureStore
from lasercal.collector.worlds.fake import FakeOperator, FakeRobot, Motion
from lasercal.solver.analysis.stats import cross_validate, solve_report
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session, session_meta
from lasercal.solver.identify.spot import identify, predict_spots

LAYOUT = load_layout(builtin_dir("layouts") / "thesis.yaml")
TRUTH = load_model("panda_thesis_identified")
NOMINAL = load_model("panda")
POINTS = {k: LAYOUT.points[k] for k in LAYOUT.calibration}


def fake_session(
    folder,
    per_point,
    seed=0,
    trigger=None,
    pool=None,
    wrong=None,
    disconnect_at=None,
    rangefinder=False,
    resume=False,
    **opts,
):
    """Run a capture session on the fake backend; returns (result, screen text, robot)."""
    op = FakeOperator(TRUTH, POINTS, pool or per_point, 1.0, seed, LAYOUT.aim_kwargs(), wrong)
    robot = FakeRobot(TRUTH, FakeClock(), op, seed=seed, disconnect_at=disconnect_at)
    cols = list(robot.extra_columns) + (["laser_length_measured"] if rangefinder else [])
    store = (
        CaptureStore.open(folder)
        if resume
        else CaptureStore.create(folder, session_meta("panda", LAYOUT, 825.0), 7, cols)
    )
    out = io.StringIO()
    rf = FakeRangefinder(robot, LAYOUT.plane_z, seed=seed) if rangefinder else None
    opts = CaptureOptions(per_point, **{"auto_discard": trigger is None, **opts})
    try:
        res = run_capture(
            store,
            robot,
            trigger or AutoTrigger(),
            NOMINAL,
            opts,
            out,
            rf,
            resume_hint=f"lasercal capture --resume {folder}",
        )
    finally:
        store.close()
    return res, out.getvalue(), robot


@pytest.fixture(scope="module")
def full_session(tmp_path_factory):
    """15 captures at each of P1-P3, 1 mm aiming noise, seed 0 (the thesis's experiment)."""
    folder = tmp_path_factory.mktemp("fake") / "s"
    res, screen, robot = fake_session(folder, 15)
    return load_session(folder), res, screen, robot


def test_auto_session_calibrates_the_fake_robot_to_its_aiming_noise(full_session):
    s, res, _, _ = full_session
    assert res.complete and res.counts == {"P1": 15, "P2": 15, "P3": 15}
    # the simulated operator realised the aiming noise it was given: 1 mm per axis (true robot, independent of
    # the solver)
    true_spots, _ = predict_spots(TRUTH, s.q, s.target[:, 2])
    assert 0.75 < np.std(true_spots[:, :2] - s.target[:, :2]) < 1.25
    ident = identify(s, "lm")
    cv = cross_validate(s, "lm", 5).as_dict()
    rep = solve_report(s, ident)
    assert 0.7 < rep["sigma_mm"] < 1.4  # the fit sees about the aiming noise per axis
    assert cv["holdout_rms_mm"] < 3.0  # held-out error near the noise (radial RMS of 1 mm per axis: 1.41 mm)
    assert cv["nominal_rms_mm"] > 4 * cv["holdout_rms_mm"]


def test_captures_are_taken_only_at_standstill(full_session):
    s, _, screen, robot = full_session
    opts = CaptureOptions(15)
    assert np.abs(s.dq).max(axis=1).max() < opts.speed_threshold
    assert np.all(np.diff(s.t) > opts.hold)
    # the logged pose is where the operator let go, up to the decaying release jiggle (<= tau * threshold)
    k = {nm: 0 for nm in POINTS}
    target = []
    for nm in s.point:
        target.append(robot.operator.configuration(nm, k[nm], 0))
        k[nm] += 1
    off = np.abs(s.q - np.array(target)).max(axis=1)
    assert off.max() < robot.motion.settle_tau * opts.speed_threshold
    assert off.min() > 0  # captured during the settling, not at a teleported pose
    assert "nominal model: the beam lands" in screen and "[###" in screen


def test_an_arm_that_never_settles_is_not_captured(tmp_path):
    noisy = FakeRobot(
        TRUTH, FakeClock(), FakeOperator(TRUTH, POINTS, 1, 1.0, 0, LAYOUT.aim_kwargs()), Motion(dq_noise=0.02)
    )
    store = CaptureStore.create(tmp_path / "s", session_meta("panda", LAYOUT, 825.0), 7, noisy.extra_columns)
    out = io.StringIO()
    res = run_capture(
        store,
        noisy,
        EnterTrigger(iter(["", "q"]).__next__),
        NOMINAL,
        CaptureOptions(1, still_timeout=5.0),
        out,
    )
    store.close()
    assert "did not come to rest within 5 s" in out.getvalue()
    assert not res.complete and load_session(tmp_path / "s").m == 0


def test_a_capture_aimed_at_the_wrong_point_is_flagged_and_discarded(tmp_path):
    res, screen, _ = fake_session(tmp_path / "s", 4, wrong={("P1", 2): "P2"})
    assert "the beam lands nearest to P2, not P1: aimed at the wrong point?" in screen
    assert res.discarded == 1 and res.counts == {"P1": 4, "P2": 4, "P3": 4}
    s = load_session(tmp_path / "s")
    spots, _ = predict_spots(NOMINAL, s.q, s.target[:, 2])
    assert np.linalg.norm(spots[:, :2] - s.target[:, :2], axis=1).max() < CaptureOptions(4).check_mm


def test_similar_poses_are_reported_with_joints_to_vary(tmp_path):
    # an operator who always returns to the same pose (a pool of one)
    _, screen, _ = fake_session(tmp_path / "s", 3, pool=1)
    assert "similar to capture #1 at P1" in screen
    assert "vary joints" in screen
    _, diverse, _ = fake_session(tmp_path / "d", 3)
    assert "similar to" not in diverse


def test_enter_trigger_captures_discards_and_quits(tmp_path):
    keys = iter(["", "", "x", "d", "", "q"])
    res, screen, _ = fake_session(tmp_path / "s", 5, trigger=EnterTrigger(keys.__next__, io.StringIO()))
    assert (res.captured, res.discarded, res.complete) == (3, 1, False)
    assert load_session(tmp_path / "s").m == 2
    assert f"resume with: lasercal capture --resume {tmp_path / 's'}" in screen


def test_disconnect_keeps_captures_and_resume_ends_where_an_uninterrupted_session_ends(tmp_path):
    fake_session(tmp_path / "ref", 5)
    ref = load_session(tmp_path / "ref")
    with pytest.raises(RobotConnectionError) as e:
        fake_session(tmp_path / "s", 5, disconnect_at=ref.t[6] + 1.0)
    assert "connection lost" in str(
        e.value
    ) and f"resume with: lasercal capture --resume {tmp_path / 's'}" in str(e.value)
    cut = load_session(tmp_path / "s")
    assert cut.m == 7
    np.testing.assert_array_equal(cut.q, ref.q[:7])  # nothing on disk was touched by the failure
    res, _, _ = fake_session(tmp_path / "s", 5, resume=True)
    s = load_session(tmp_path / "s")
    assert res.complete and res.captured == 8
    assert list(s.point) == list(ref.point)
    np.testing.assert_array_equal(s.q, ref.q)  # the same captures as without the disconnect, bit for bit
    assert np.all(np.diff(s.t) > 0)


def test_rangefinder_lengths_are_logged(tmp_path):
    fake_session(tmp_path / "s", 2, rangefinder=True)
    s = load_session(tmp_path / "s")
    measured = s.extra["laser_length_measured"].astype(float)
    _, true_length = predict_spots(TRUTH, s.q, s.target[:, 2])
    assert np.abs(measured - true_length).max() < 2.0  # 0.5 mm noise
    assert np.ptp(true_length) > 50  # the poses really differ in length


def test_a_photo_taken_while_the_arm_creeps_is_measured_in_mm_of_spot_and_a_simulated_clock_is_not_read():
    """The read after a capture's photo (sessions.standstill.moved_during_photo): how far the spot moved under
    the nominal model since the standstill read the row logs -- in mm on the plane, so joint 7's spin about
    the beam (franky-sim's chatter) counts for what it moves the spot, not for its angle."""
    from lasercal.collector.hardware.base import Clock, FakeClock, JointState
    from lasercal.collector.sessions.standstill import PHOTO_MOVED_MM, moved_during_photo
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.identify.spot import predict_spots

    panda = load_model("panda")
    q0 = np.asarray(panda.home, dtype=float)

    class Creeping:  # an arm on wall time that turned by `step` since the standstill read
        def __init__(self, step, clock):
            self.step, self.clock = step, clock

        def read(self):
            return JointState(q0 + self.step, np.zeros(7), np.zeros(7), 0.0, {})

    still = JointState(q0, np.zeros(7), np.zeros(7), 0.0, {})
    for j, turn in ((1, 1e-5), (6, 1e-4)):
        step = np.zeros(7)
        step[j] = turn
        want = np.linalg.norm(np.diff(predict_spots(panda, np.array([q0, q0 + step]), -8.0)[0], axis=0))
        got = moved_during_photo(Creeping(step, Clock()), still, panda, -8.0)
        assert got == pytest.approx(want, rel=1e-9)
    shoulder = np.r_[0, 2e-5, 0, 0, 0, 0, 0]  # joint 2 by 2e-5 rad: 0.007 mm at the spot, a retake
    assert moved_during_photo(Creeping(shoulder, Clock()), still, panda, -8.0) > PHOTO_MOVED_MM
    # a simulated clock cannot move the arm between the read and the photo: not read (its reads draw noise)
    assert moved_during_photo(Creeping(shoulder, FakeClock()), still, panda, -8.0) == 0.0
