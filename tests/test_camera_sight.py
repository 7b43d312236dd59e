"""Issue 53: the coach of a hands-free camera session plans only poses its camera can measure. Where the
camera stands comes from a photo's markers (vision.plane.camera_eye, eq. V2), whether it sees a spot and the
markers past the arm from the model (solver.analysis.sight, eq. V1)."""

from __future__ import annotations

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lasercal.collector.worlds.truearm import arm_segments
from lasercal.solver.analysis.design import Coach
from lasercal.solver.analysis.sight import arm_axes, camera_sees, segment_distance
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout
from lasercal.solver.kinematics.laser import beam, plane_hit
from lasercal.vision.plane import camera_eye
from lasercal.vision.render import look_down

PANDA = load_model("panda")


@settings(max_examples=40, deadline=None)
@given(
    st.floats(5, 40), st.floats(-40, 40), st.floats(-180, 180), st.floats(300, 1500), st.integers(0, 10**6)
)
def test_the_eye_of_a_tilted_camera_is_found_from_its_homography(tilt_x, tilt_y, yaw, height, seed):
    """eq. V2 against the renderer's own pinhole (vision.render.look_down): the centre to 1e-4 of its
    distance (measured over 400 draws at 5-50 deg of tilt: at most 9.2e-6, the homography's own fit by
    OpenCV setting it); points anywhere on the plane."""
    view = look_down(
        (1280, 960), 0.3, centre=(120.0, -40.0), yaw_deg=yaw, tilt_deg=(tilt_x, tilt_y), height=height
    )
    xy = np.random.default_rng(seed).uniform(-150, 150, (8, 2)) + [120.0, -40.0]
    H, _ = cv2.findHomography(view.project(xy), xy, 0)
    eye = camera_eye(H, view.size)
    assert eye is not None
    assert np.linalg.norm(eye - [120.0, -40.0, height]) < 1e-4 * height


def test_a_square_on_camera_says_it_cannot_tell():
    """Within EYE_MIN_TILT_DEG of square-on the focal length is not determined: None, not a guess (the
    unguarded formula puts such a camera ~580 m up)."""
    view = look_down((1280, 960), 0.3, centre=(0.0, 0.0), tilt_deg=(1.0, 0.0), height=700.0)
    xy = np.array([[0, 0], [200, 0], [200, 150], [0, 150.0]]) - 100
    H, _ = cv2.findHomography(view.project(xy), xy, 0)
    assert camera_eye(H, view.size) is None


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6))
def test_segment_distance_is_the_sampled_minimum(seed):
    a0, a1, b0, b1 = np.random.default_rng(seed).normal(size=(4, 3)) * 100
    s = np.linspace(0, 1, 1201)[:, None]
    brute = np.linalg.norm((a0 + s * (a1 - a0))[:, None] - (b0 + s * (b1 - b0))[None], axis=2).min()
    got = float(segment_distance(a0, a1, b0, b1))
    assert got <= brute + 1e-9 and brute - got < 0.5  # the samples lie within 0.2 mm of the true closest


def test_the_arm_the_coach_sees_is_the_one_the_world_draws():
    """solver.analysis.sight's centre line (the solver's POE chain) against the fake world's (scipy's
    expm)."""
    q = np.random.default_rng(3).uniform(-1.5, 1.5, (5, PANDA.n))
    axes = arm_axes(PANDA, q)
    for a, qi in zip(axes, q):
        seg = arm_segments(PANDA, qi)
        assert np.abs(a[:-1] - seg[:, 0]).max() < 1e-9 and np.abs(a[1:] - seg[:, 1]).max() < 1e-9


def test_a_camera_behind_the_arm_does_not_see_the_spot():
    """A camera placed on the line from the spot through a link's middle, beyond it, is hidden; the same
    camera lifted far above the table sees the spot; a marker behind the arm counts as hidden too."""
    layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
    q = layout.aim_at(PANDA, "P1", 1, np.random.default_rng(0))
    b = beam(np.asarray(PANDA.screws), PANDA.laser_dir, PANDA.aperture, q)
    spot, _ = plane_hit(b.aperture, b.direction, layout.plane_z)
    axes = arm_axes(PANDA, q)[0]
    middle = (axes[3] + axes[4]) / 2  # the upper arm's centre line
    behind = spot[0] + 2.5 * (middle - spot[0])
    far_above = spot[0] + np.array([0.0, 0.0, 5000.0])
    markers = np.array([spot[0] + [60.0, 0, 0], spot[0] + [-60.0, 0, 0]])
    z = layout.plane_z
    assert not camera_sees(PANDA, q, z, behind, markers, 0)[0]
    assert camera_sees(PANDA, q, z, far_above, markers, 2)[0] or np.linalg.norm(b.direction[0, :2]) > 0.3
    assert not camera_sees(PANDA, q, z, far_above, markers, 3)[0]  # two markers cannot make three


def test_the_coach_plans_no_pose_its_camera_cannot_measure():
    """Coach.see_from sets aside the candidates a camera would not measure, and the plan draws on the
    others only; a point none of whose candidates the camera sees keeps them (the coach cannot help)."""
    layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
    coach = Coach(PANDA, layout, seed=1, per_point=40)
    eye = np.array([450.0, 0.0, 700.0])  # straight above the points: the arm hides 42 % of the candidates
    markers = np.array([[x, y, layout.plane_z] for x in (300.0, 650.0) for y in (-300.0, 300.0)])
    aside = coach.see_from(eye, markers, 3)
    c = coach.cand
    seen = camera_sees(PANDA, c.q, c.target[:, 2], eye, markers, 3)
    assert 0 < aside == int((~seen).sum()) < len(c.q)
    st = coach.status(np.empty((0, PANDA.n)), k=10)
    plan_seen = camera_sees(PANDA, st.plan.q, st.plan.target[:, 2], eye, markers, 3)
    assert plan_seen.all()


def test_a_point_the_camera_cannot_measure_borrows_the_seen_candidates_nearest_it():
    """A point whose every candidate lies past the markers the photo shows (the over-the-arm placement's P5,
    a marker out of frame) is planned where the camera measures: its share of the seen candidates nearest
    it, relabelled to it; the others keep theirs. (Before: it kept its own, none measurable.)"""
    layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
    coach = Coach(PANDA, layout, seed=1, per_point=40)
    before = coach.cand
    eye = np.array([450.0, 0.0, 2000.0])
    z = layout.plane_z
    markers = np.array([[x, y, z] for x in (300.0, 650.0) for y in (-100.0, 300.0)])  # P3 (y -200) outside
    coach.see_from(eye, markers, 3)
    c = coach.cand
    seen = camera_sees(PANDA, c.q, c.target[:, 2], eye, markers, 3)
    assert not seen[before.point == "P3"].any()
    lent = c.available(["P3"])
    assert lent.sum() == int(seen.sum()) // 3 and seen[lent].all()
    assert np.allclose(c.anchor[lent], layout.points["P3"])
    assert np.allclose(c.target[lent, :2], layout.points["P2"][:2], atol=1.0)  # the nearest seen: P2's
    for name in ("P1", "P2"):
        assert c.available([name]).sum() > 0
    st = coach.status(np.empty((0, PANDA.n)), k=10, allowed=["P3"])
    assert camera_sees(PANDA, st.plan.q, st.plan.target[:, 2], eye, markers, 3).all()


def test_two_points_the_camera_cannot_measure_each_keep_their_own_share():
    """P1 and P3 both past the markers' hull: each borrows its full share of P2's seen candidates, and the
    second does not take back what the first borrowed."""
    layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
    coach = Coach(PANDA, layout, seed=1, per_point=40)
    z = layout.plane_z
    markers = np.array([[x, y, z] for x in (300.0, 650.0) for y in (-100.0, 100.0)])
    coach.see_from(np.array([450.0, 0.0, 2000.0]), markers, 3)
    c = coach.cand
    share = int((~c.hidden).sum()) // 3
    assert c.available(["P1"]).sum() == share == c.available(["P3"]).sum() > 0


def test_a_spot_outside_the_markers_the_photo_shows_is_not_planned():
    """The photo maps to mm only inside the hull of the markers it shows: a spot outside it, or with fewer
    than three shown, is not measurable."""
    from lasercal.solver.analysis.sight import inside_shown

    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10.0]])
    spots = np.array([[5, 5], [11, 5], [5, 5], [2, 8]])
    shown = np.array([[1, 1, 1, 1], [1, 1, 1, 1], [1, 0, 1, 0], [1, 1, 1, 0]], bool)
    assert inside_shown(spots, square, shown).tolist() == [True, False, False, False]


def test_a_marker_the_arm_hides_in_part_is_not_shown():
    """Given its corners, a marker counts as in sight only when every corner is: one whose corner lies
    behind the arm while its centre is clear is not found in the photo. Given its centre alone, the same
    marker counts (and with it the spot is planned)."""
    from lasercal.solver.analysis.sight import sight_clear

    layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
    q = layout.aim_at(PANDA, "P1", 1, np.random.default_rng(0))
    axes, z = arm_axes(PANDA, q), layout.plane_z
    b = beam(np.asarray(PANDA.screws), PANDA.laser_dir, PANDA.aperture, q)
    spot = plane_hit(b.aperture, b.direction, z)[0][0]
    eye = spot + np.array([0.0, 0.0, 3000.0])  # far above: the arm hides what lies under it

    def clear(p):
        return sight_clear(axes, eye, np.asarray(p, dtype=float).reshape(1, -1, 3))[0]

    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0.0]])
    around = [spot + d for d in ([250.0, 250, 0], [-250.0, 250, 0], [-250.0, -250, 0], [250.0, -250, 0])]
    rng, corners = np.random.default_rng(0), []
    for c in around:  # the first of each corner's sampled markers (80 mm wide): clear, or half hidden
        for _ in range(2000):
            m = c + rng.uniform(-120, 120, 3) * [1, 1, 0] + 40 * square
            ok = clear(m).all() if len(corners) < 3 else (clear(m.mean(0)).all() and not clear(m).all())
            if ok:
                corners.append(m)
                break
    corners = np.array(corners)
    assert len(corners) == 4 and clear(spot).all()
    assert camera_sees(PANDA, q, z, eye, corners.mean(axis=1), 4)[0]  # by the centres: 4 markers, the spot
    assert not camera_sees(PANDA, q, z, eye, corners, 4)[0]  # by the corners: 3
    assert camera_sees(PANDA, q, z, eye, corners, 3)[0]


def test_the_markers_in_view_are_recorded_and_a_resume_reads_them(tmp_path):
    """camera_eye.yaml keeps the first measured photo's eye and the markers it found: a resumed session
    plans with the same, and a file from before the key holds every marker in view (an empty tuple)."""
    from lasercal.collector.sessions.coaching import EYE_FILE, recorded_view

    eye = np.array([350.0, -1.25, 600.5])
    got = recorded_view(tmp_path, eye, (0, 2, 5))
    again = recorded_view(tmp_path, None)  # as a resume: nothing measured yet
    assert np.allclose(got[0], eye) and got[1] == (0, 2, 5)
    assert np.allclose(again[0], eye) and again[1] == (0, 2, 5)
    (tmp_path / EYE_FILE).write_text("eye_mm: [350.0, -1.25, 600.5]\n")
    assert recorded_view(tmp_path, None)[1] == ()
