"""Issue 38: the camera measures every capture -- the fake camera's spots against the simulated truth, a
spot the camera cannot see, and a session mixing measured and aimed captures fitted with a noise each."""

from __future__ import annotations

import io

import numpy as np
import pytest

from lasercal.collector.hardware import make_robot
from lasercal.collector.sessions.settings import capture_settings
from lasercal.collector.sessions.spotcam import BESIDE_MM, capture_camera
from lasercal.collector.sessions.start import CaptureGuide, start_capture
from lasercal.collector.worlds.fakeworld import EFFECTS, World, table_points
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout, load_session, session_meta, write_session
from lasercal.solver.identify.spot import identify_lm, predict_spots
from lasercal.solver.kinematics.aim import aim, polish
from lasercal.vision.errors import VisionError

ROUNDS = 13  # of the sheet's 5 calibration points: 65 photos, ~50 seen (the arm hides a quarter)
# benchmarks/bench_camera_sigma.py both 200 7 3 (949 photos, every effect, world seed 3), --bounds 45:
# 45-photo sessions resampled 200,000 times, the 0.1 % and 99.9 % quantiles of the z-score RMS; the largest
# |z| from the photos' tail (``largest_bound``: the bootstrap 95 % upper limit of a generalised Pareto fit's
# 99.9 % session quantile, 4.19). It was the resampled quantile, 3.91: the largest of the 949 photos, which a
# fresh 45-photo session passes in about 1 of 21 (90 values against 1,898).
EVERY_EFFECT_Z_RMS_45 = (0.720, 1.254)
EVERY_EFFECT_LARGEST_Z_45 = 4.79


def test_measured_spots_lie_within_their_stated_uncertainty(sheet):
    """Monte Carlo over the fake camera's photos with every effect on (a world seed whose printer, sheet
    height, table slope and paper bulge draws are not small; the lens corrected by camera-calibrate's
    estimate): each measured spot against where the true beam met the paper, in the layout's printed
    coordinates (the world's own code), divided by its stated 1-sigma. A z-score RMS near 1 means the
    uncertainty says what the measurement does; far above 1 it would promise too much, far below it would
    waste the data.

    How near: within the 0.1 % and 99.9 % quantiles of the z-score RMS of 45-photo sessions resampled
    200,000 times from 949 photos of this world (every effect, seed 3, spots beside the five crosses;
    benchmarks/bench_camera_sigma.py both 200 7 3, then --bounds 45), and no z-score beyond the largest
    such a session exceeds 1 in 1,000 times (a tail model of those photos). A sigma 1.5x too large or too
    small leaves the band (checked by scaling it). Before issue 51 the stated sigma was 1.6x too large here
    (RMS 0.61; the homography's misfit counted 1.8x) and the band was 0.56-1.22."""
    layout = load_layout(sheet)
    world = World.draw(EFFECTS, 3)
    assert np.abs(world.print_scale - 1).max() > 5e-4 and abs(world.sheet_dz) > 0.1  # the effects bite
    assert np.linalg.norm(world.slope) > 2e-3 and world.bulge > 0.15
    cfg = {"backend": "fake", "truth": "panda_thesis_identified", "aim_noise": 3.0, "seed": 3}
    points = table_points(layout, world, BESIDE_MM)
    robot = make_robot(
        cfg, load_model("panda"), layout.in_base(), 3, points=points, repeat_sigma=world.repeat_sigma
    )
    camera, measure = capture_camera("fake", cfg, robot, layout, sheet, world)
    robot.connect()
    z, lost = [], 0
    for k in range(ROUNDS):
        for name in layout.calibration:
            robot.prompt_point(name, None, k)
            robot.clock.sleep(10.0)  # transit and release jiggle over
            img = camera.photo()
            true = camera.paper.hit(*robot.true_beam())[0][0]  # where the beam met the paper, as printed
            try:
                m = measure(img, f"{name}-{k}")
            except VisionError:
                lost += 1  # hidden by the arm: the next test's case
                continue
            z.append((m.xy - true) / m.sigma)
    z = np.array(z)
    k, rms = z.size, float(np.sqrt(np.mean(z**2)))
    print(
        "z-score RMS", rms, "per axis", np.sqrt(np.mean(z**2, axis=0)), "max", np.abs(z).max(), "lost", lost
    )
    assert k >= 90, lost
    assert EVERY_EFFECT_Z_RMS_45[0] < rms < EVERY_EFFECT_Z_RMS_45[1], rms
    assert np.abs(z).max() < EVERY_EFFECT_LARGEST_Z_45, z


def test_a_hidden_spot_is_said_at_once_and_kept_as_an_aimed_capture(sheet, tmp_path, monkeypatch):
    """docs/sessions.md: a spot the camera cannot measure is said at once, with why; the capture keeps its
    photo and is kept as an aimed one (--auto's rule), fitted to where the operator aimed; --resume
    continues the camera session from its folder alone."""
    import lasercal.collector.worlds.cameras as cameras

    monkeypatch.setattr(cameras, "hidden", lambda *a, **k: True)  # the arm over every line of sight
    given = {"backend": "fake", "per_point": 1, "camera": "fake", "aim_noise": 3.0, "seed": 1}
    folder = tmp_path / "s"
    out = io.StringIO()
    start_capture(capture_settings(given, str(sheet), str(folder)), CaptureGuide(auto=True, coach=False)).run(
        out
    )
    said = out.getvalue()
    assert said.count("the spot could not be measured (no red or green laser spot found") == 5, said
    assert "kept as an aimed capture" in said
    session = load_session(folder)
    assert session.m == 5 and not session.measured.any()
    assert all((folder / p).is_file() for p in session.extra["photo"])
    assert all(n for n in session.extra["camera_note"])
    layout = load_layout(sheet)
    cross = np.array([layout.points[p][:2] for p in session.point])
    np.testing.assert_allclose(session.target[:, :2], cross + BESIDE_MM)  # where the operator aimed
    resumed = start_capture(capture_settings({}, resume=str(folder)), CaptureGuide(auto=True, coach=False))
    assert resumed.camera is not None
    out = io.StringIO()
    assert resumed.run(out).complete
    assert load_session(folder).m == 5


def test_a_mixed_session_finds_the_noise_of_each_kind(tmp_path):
    """Half the captures measured (stated uncertainty 0.02-0.06 mm plus 0.05 mm the camera does not see,
    the arm's repeatability), half aimed at their crosses with 1 mm of aiming noise: the fit finds each
    kind's noise (eq. K2), within the spread of a noise estimate from ~45 captures' residuals."""
    truth = load_model("panda_thesis_identified")
    layout = load_layout("thesis")
    rng = np.random.default_rng(38)
    s_a, s_m = 1.0, 0.05
    names, q, cells = [], [], {k: [] for k in ("camera_x", "camera_y", "camera_sx", "camera_sy")}
    for name in layout.calibration:
        p = layout.points[name]
        for k, q0 in enumerate(aim(truth, p, 30, rng, **layout.aim_kwargs())):
            measured = k % 2 == 0
            hit = p + np.r_[rng.normal(0, s_a, 2), 0.0]
            qi = polish(truth, q0[None], hit)[0]
            names.append(name)
            q.append(qi)
            if measured:
                u = rng.uniform(0.02, 0.06)
                spot = predict_spots(truth, qi[None], p[2])[0][0, :2] + rng.normal(0, np.hypot(u, s_m), 2)
                for key, v in zip(cells, (*spot, u, u)):
                    cells[key].append(repr(float(v)))
            else:
                for key in cells:
                    cells[key].append("")
    meta = session_meta("panda", layout, None)
    t = np.arange(len(q), dtype=float)
    folder = write_session(tmp_path / "mixed", meta, names, t, np.array(q), extra=cells)
    session = load_session(folder)
    assert session.measured.sum() == 45
    noise = identify_lm(session).extra["noise"]
    assert noise["measured"] == 45 and noise["aimed"] == 45
    assert 0.8 < noise["aimed_mm"] / s_a < 1.25, noise
    truth_measured = np.sqrt(np.mean(session.spot_sigma[session.measured] ** 2) + s_m**2)
    assert 0.75 < noise["measured_mm"] / truth_measured < 1.3, noise
    assert 0.025 < noise["unseen_mm"] < 0.075, noise


def test_hands_free_the_arm_drives_itself_and_the_camera_measures_each(sheet, tmp_path):
    """--guide move with a camera: no hand -- the fake arm moves (at its bounded speed, on the simulated
    clock) to each of the coach's poses, aimed anywhere on the sheet (--aim anywhere, the default), and the
    camera measures every capture."""
    given = {"backend": "fake", "per_point": 1, "camera": "fake", "aim_noise": 3.0, "seed": 2}
    out = io.StringIO()
    guide = CaptureGuide(auto=True, move=True, yes=True)
    start_capture(capture_settings(given, str(sheet), str(tmp_path / "s")), guide).run(out)
    said = out.getvalue()
    assert said.count("hands-free") >= 5 and "the camera measures where the beam lands" in said
    session = load_session(tmp_path / "s")
    assert session.m == 5
    measured = session.measured
    assert measured.sum() >= 4, said  # a pose the camera cannot see is guided by hand once (then aimed)
    # nobody guided a pose the camera saw: hands were on the arm only once per pose it could not see
    modes = session.extra["robot_mode"]
    assert np.sum(modes == "Guiding") <= said.count("guided by hand once") and np.sum(modes == "Move") >= 3
    aim = np.c_[session.extra["aim_x"].astype(float), session.extra["aim_y"].astype(float)]
    off = np.linalg.norm(session.target[measured, :2] - aim[measured], axis=1)
    # where the coach planned the spot, up to its current fit's error there (the arm goes where that fit
    # aims; after 0-4 captures, the thesis Panda against the nominal: 4-25 mm seen over seeds 2-5)
    assert np.all(off < 35.0) and np.median(off) < 15.0, off


@pytest.mark.parametrize("coach", [False, True])
def test_a_camera_session_killed_and_resumed_repeats_the_uninterrupted_one(sheet, tmp_path, coach):
    """Crash-safe as an aimed session: a lost link keeps every capture and photo on disk, and --resume ends
    where an uninterrupted session ends, measured spots included (the photos' noise is keyed by the pose);
    with the coach, the spots it planned anywhere on the sheet too (it refits the same captures)."""
    from lasercal.collector.errors import RobotConnectionError

    given = {"backend": "fake", "per_point": 1, "camera": "fake", "aim_noise": 3.0, "seed": 4 + 3 * coach}
    guide = CaptureGuide(auto=True, coach=coach)
    start_capture(capture_settings(given, str(sheet), str(tmp_path / "ref")), guide).run(io.StringIO())
    ref = load_session(tmp_path / "ref")
    cut = start_capture(capture_settings(given, str(sheet), str(tmp_path / "s")), guide)
    cut.robot.disconnect_at = ref.t[1] + 1.0
    with pytest.raises(RobotConnectionError):
        cut.run(io.StringIO())
    assert load_session(tmp_path / "s").m == 2
    start_capture(capture_settings({}, resume=str(tmp_path / "s")), guide).run(io.StringIO())
    s = load_session(tmp_path / "s")
    np.testing.assert_array_equal(s.q, ref.q)
    np.testing.assert_array_equal(s.target, ref.target)  # the camera measured the same spots
    np.testing.assert_array_equal(s.spot_sigma, ref.spot_sigma)
    assert len(list((tmp_path / "s" / "photos").iterdir())) == 5
    assert (s.meta["collector"]["aim"] == "anywhere") == coach
    for k in ("aim_x", "aim_y") if coach else ():
        np.testing.assert_array_equal(s.extra[k], ref.extra[k])
