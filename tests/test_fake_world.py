"""Issue 45 item 8: a world not drawn by the solver -- the fake world's beam, paper, lens and spot by its own
code, what no model term holds (a bulging, skewed paper; a lens corrected by an estimate; a spot whose
brightness is not symmetric about the beam's hit), and solve recovering a drawn print scale and tilt."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.collector.worlds import truearm
from lasercal.collector.worlds.fakeworld import EFFECTS, World, camera_lens, lens_estimate
from lasercal.collector.worlds.truelens import Lens, SheetView, SpaceCamera, look_at
from lasercal.collector.worlds.truesheet import PaperSheet
from lasercal.collector.worlds.truespot import GLOW_FRACTION, PAPER_INDEX, SCATTER_DEPTH_MM, footprint
from lasercal.solver.formats.robots import load_model
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim
from lasercal.vision.camera import undistort

TRUTH = load_model("panda_thesis_identified")


def test_the_worlds_beam_is_the_robots_by_independent_code():
    """The world's chain of matrix exponentials and the solver's POE give the same spots (two independent
    implementations of one robot: a slip in either shows)."""
    q = aim(TRUTH, np.array([450.0, 20.0, -8.0]), 6, np.random.default_rng(1))
    q = q + np.random.default_rng(2).normal(0, 0.05, q.shape)  # off the point: any configuration
    world = np.array([truearm.plane_spot(*truearm.beam(TRUTH, qk), -8.0)[0] for qk in q])
    np.testing.assert_allclose(world, predict_spots(TRUTH, q, -8.0)[0], rtol=0, atol=1e-8)


def test_a_sheet_as_printed_and_laid_bulged_and_skewed():
    """eqs. W1-W3: a printed point goes to the paper (scale, skew), onto the sloping table, lifted by the
    bulge (A along the middle, 0 at the taped ends); a ray finds it again."""
    paper = PaperSheet(
        np.array([450.0, 3.0, -8.0]), 0.3, np.array([1.002, 0.998]), 1e-3, np.array([3e-3, -2e-3]), 0.25
    )
    uv = np.array([[0.0, 0.0], [50.0, 148.5 / 0.998], [-80.0, -100.0], [30.0, 74.25 / 0.998]])
    p = paper.surface(uv)
    e1, e2, n = paper.axes
    rel = p - paper.centre
    bulge = 0.25 * np.cos(np.pi * np.array([0.0, 148.5, -99.8, 74.25]) / 297) ** 2  # at b = 0.998 v
    np.testing.assert_allclose(rel @ n, bulge, rtol=0, atol=1e-9)
    assert abs(bulge[1]) < 1e-12 and bulge[3] == pytest.approx(0.125)
    # the skew: the print's y axis leans along x by 1e-3 (0.15 mm over 148.5 mm)
    np.testing.assert_allclose(rel[1] @ e1, 1.002 * 50 + 1e-3 * 148.5, rtol=0, atol=1e-9)
    # the table rises 3 mrad along the sheet's x: e1 climbs
    assert abs(e1[2] - 3e-3 / np.sqrt(1 + 9e-6)) < 1e-5
    rays = np.random.default_rng(0).normal(0, 0.3, (4, 3)) + [0.2, 0.1, -1.0]
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    start = p - 400.0 * rays
    back, hit, s = paper.hit(start, rays)
    np.testing.assert_allclose(back, uv, atol=1e-9)
    np.testing.assert_allclose(s, 400.0, atol=1e-9)


def test_the_lens_and_its_inverse():
    """eq. L1 and the rays of recorded pixels: a round trip to 1e-9 px over the whole photo."""
    lens = camera_lens(World(("distortion",)))
    uv = np.stack(np.meshgrid(np.linspace(0, 1279, 9), np.linspace(0, 959, 7)), -1).reshape(-1, 2)
    np.testing.assert_allclose(lens.pixels(lens.rays(uv)), uv, atol=1e-9)


def test_the_lens_is_corrected_by_camera_calibrates_estimate_not_by_its_own_parameters():
    """The correction a session applies is what camera-calibrate estimates from chessboard photos rendered
    through the lens (its model: k1, k2, p1, p2; the lens also has k3 and a thin prism): close to the truth,
    not it. Measured on a plane seen as the sheet is: after the homography the markers fit, the corrected
    pixels are within 0.3 px of the truth, and not exact."""
    import cv2

    est, lens = lens_estimate(), camera_lens(World(("distortion",)))
    assert est.rms_px < 0.1  # camera-calibrate's own reprojection RMS on the rendered photos
    assert abs(est.dist[0] - lens.radial[0]) > 1e-4 and abs(est.dist[4]) == 0.0  # k3 held at 0: not the truth
    grid = np.stack(np.meshgrid(np.linspace(40, 1240, 13), np.linspace(40, 920, 9)), -1).reshape(-1, 2)
    ideal = lens.rays(grid) * np.diag(lens.K)[:2] + lens.K[:2, 2]  # the true ideal pixels
    corrected = undistort(grid, est.K, est.dist)
    H, _ = cv2.findHomography(corrected, ideal)
    mapped = cv2.perspectiveTransform(corrected.reshape(-1, 1, 2), H).reshape(-1, 2)
    err = np.linalg.norm(mapped - ideal, axis=1)
    assert 1e-3 < err.max() < 0.3, err.max()


def _spot_centre(paper, view, uv, d, subsurface, seed):
    """The measured centre (printed mm) of one rendered spot through a known view."""
    from lasercal.collector.sessions.validate import measure_known_view
    from lasercal.vision.render import Photo, render

    spots = footprint(view, paper, uv, d, True, subsurface)
    return measure_known_view(render(Photo(view, (), spots), seed=seed), "spot", view)[0]


def test_the_spots_brightness_is_not_symmetric_about_the_beams_hit():
    """eq. F2: a beam 40 deg off the normal; with the paper's subsurface light, the measured spot lies
    downstream of the hit by ~f d_s tan r (0.024 mm), across it not at all; without it, on the hit (medians
    over 24 photos, each with its own speckle and noise: the detector reads an odd photo's speckled rim far
    off -- issue 47's reads the null set's photo 20 0.25 mm off, 3.6 of its stated sigmas -- and a mean of
    24 would carry a tenth of that)."""
    paper = PaperSheet(np.array([450.0, 0.0, -8.0]))
    below = paper.surface(np.zeros((1, 2)))[0]
    R, t = look_at(below + [0.0, 0.0, 800.0], below, up=(1.0, 0.0, 0.0))
    K = np.array([[4000.0, 0, 399.5], [0, 4000.0, 299.5], [0, 0, 1.0]])
    view = SheetView(SpaceCamera(Lens((800, 600), K), R, t), paper)
    i = np.radians(40.0)
    d = np.array([np.sin(i) * np.cos(0.5), np.sin(i) * np.sin(0.5), -np.cos(i)])  # azimuth 0.5 rad
    along, across = d[:2] / np.linalg.norm(d[:2]), np.array([-d[1], d[0]]) / np.linalg.norm(d[:2])
    r = np.arcsin(np.sin(i) / PAPER_INDEX)
    expected = GLOW_FRACTION * SCATTER_DEPTH_MM * np.tan(r)
    uv = np.array([5.0, -3.0])
    shifts = {
        s: np.array([_spot_centre(paper, view, uv, d, s, k) - uv for k in range(24)]) for s in (False, True)
    }
    glow = np.median(shifts[True], axis=0)
    assert abs(glow @ along - expected) < 0.008, (glow @ along, expected)
    assert abs(glow @ across) < 0.006
    assert np.linalg.norm(np.median(shifts[False], axis=0)) < 0.006
    assert expected > 0.02


@pytest.fixture(scope="module")
def scaled_session(tmp_path_factory):
    """A camera session (45 captures, the coach, the sheet at 450 0 0) in a world whose printer scaled the
    sheet by +0.17 % and -0.19 % and whose table slopes 3.2 mrad (seed 93), solved."""
    d = tmp_path_factory.mktemp("scaled")
    world = World.draw(("print-scale", "table-slope"), 93)
    assert np.all(np.abs(world.print_scale - 1) > 1.5e-3) and np.linalg.norm(world.slope) > 3e-3
    assert main(["sheet", "-o", str(d / "sheet"), "--place", "450", "0", "0"]) == 0
    capture = [
        "capture",
        "--layout",
        str(d / "sheet" / "layout.yaml"),
        "--robot",
        "panda",
        "--backend",
        "fake",
    ]
    opts = ["--auto", "--per-point", "9", "--aim-noise", "3", "--camera", "fake", "--seed", "93"]
    effects = ["--effects", "repeatability,print-scale,table-slope"]
    assert main([*capture, *opts, *effects, "-o", str(d / "s")]) == 0
    assert main(["solve", str(d / "s"), "-o", str(d / "m.yaml"), "--folds", "0"]) == 0
    return d


def test_solve_recovers_a_drawn_print_scale_and_tilt_within_its_sigma(scaled_session):
    """The found print scale and tilt against the world's own (read off its paper in the robot's own frame,
    collector.worlds.record.true_sheet_pose), in the sigmas solve reports; the tilt and the difference of
    the two scales are the data's (sigmas far below the draws), the common scale is the robot's size and
    the sheet's at once (what the prior holds, ~0.14 %)."""
    from lasercal.collector.worlds.record import session_world, true_sheet_pose

    d = scaled_session
    model = yaml.safe_load((d / "m.yaml").read_text())
    found, std = model["sheet"], model["sheet_std"]
    true, _ = true_sheet_pose(session_world(d / "s"), load_model("panda"), -8.0)
    z = {
        k: (found[k] - getattr(true, k)) / std[k] for k in ("scale_x", "scale_y", "tilt_x_rad", "tilt_y_rad")
    }
    print("found - true in sigmas", z, "found", found, "true", true)
    # The bounds are measured quantiles, not guesses: over 24 sessions (benchmarks/bench_sheet_scale_camera.py
    # 24 100: seeds 100-123, each a new world, new poses and new photos, the coach planning for the camera's
    # view) the z-scores' RMS was 0.50, 0.57, 0.95, 1.27 (pooled 0.88), the largest |z| of a session at most
    # 3.16, and under N(0, 0.88^2) a session's largest of four passes 3.21 in 0.1 % of sessions (3.5 in
    # 0.03 %). The old bound of 2 failed in 4.9 % (another CPU drew -2.30). A tilt left unfound puts |z|
    # above 5 (the table's 3 mrad against a sigma under 0.6 mrad, asserted below).
    assert all(abs(v) < 3.5 for v in z.values()), z
    assert std["tilt_x_rad"] < 0.6e-3 and std["tilt_y_rad"] < 0.6e-3  # the data see the tilt
    # the two scales' difference: its error over the same 24 sessions had mean -2.4e-5 and sd 2.67e-4 (at
    # most 4.2e-4); 99.9 % of |error| under that Gaussian is below 9.0e-4 (the bound of 3e-4 this test had,
    # never measured, failed 8 of the 24). A difference left unfound is off by the drawn 3.6e-3.
    spread = (found["scale_x"] - found["scale_y"]) - (true.scale_x - true.scale_y)
    assert abs(spread) < 9e-4 and abs(true.scale_x - true.scale_y) > 3e-3


def test_the_honest_floor_is_the_repeatability_and_the_camera(scaled_session):
    """The true robot aimed at P6 where it truly lies, photographed as validate does: its error is the arm's
    repeatability (0.05-0.06 mm at P6 over 15 poses) with the camera's few hundredths on top."""
    from lasercal.collector.studies.floors import floors

    honest, repeat = floors(scaled_session / "s", scaled_session / "sheet" / "layout.yaml", "P6", 15, 0)
    assert 0.03 < repeat < 0.09, repeat
    assert repeat * 0.9 < honest < repeat * 1.5 + 0.01, (honest, repeat)


def test_every_effect_has_a_name_and_the_world_record_round_trips():
    """--effects names (issue 38's and the new ones) and session.yaml's record: what validate and a resumed
    capture read back is the world that was drawn, the camera's calibration included."""
    assert {"table-slope", "paper-curl", "print-shear", "subsurface"} <= set(EFFECTS)
    w = World.draw(EFFECTS, 7, 140.0)
    back = World.from_dict(yaml.safe_load(yaml.safe_dump(w.as_dict())))
    np.testing.assert_array_equal(back.lens.K, lens_estimate().K)  # the calibration the session used
    np.testing.assert_array_equal(back.correction.dist, lens_estimate().dist)
    for key in ("print_scale", "slope"):
        np.testing.assert_array_equal(getattr(back, key), getattr(w, key))
    assert (back.effects, back.sheet_dz, back.bulge, back.shear, back.half_length) == (
        w.effects,
        w.sheet_dz,
        w.bulge,
        w.shear,
        140.0,
    )


def test_a_new_camera_session_measures_through_the_estimated_correction(sheet):
    """The capture camera of a new session (the world as drawn, nothing recorded yet) and of a resumed one
    (the world session.yaml recorded) correct the lens alike: by camera-calibrate's estimate."""
    from lasercal.collector.hardware import make_robot
    from lasercal.collector.sessions.spotcam import capture_camera
    from lasercal.solver.formats.session import load_layout

    layout = load_layout(sheet)
    cfg = {"backend": "fake", "truth": "panda_thesis_identified", "aim_noise": 3.0, "seed": 0}
    robot = make_robot(cfg, load_model("panda"), layout.in_base())
    drawn = World.draw(("distortion",), 0)
    recorded = World.from_dict(yaml.safe_load(yaml.safe_dump(drawn.as_dict())))
    for world in (drawn, recorded):
        camera, _ = capture_camera("fake", cfg, robot, layout, sheet, world)
        np.testing.assert_array_equal(camera.lens.dist, lens_estimate().dist)
    assert capture_camera("fake", cfg, robot, layout, sheet, World())[0].lens is None
