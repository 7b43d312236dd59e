"""Circle-point full-pose measurement (Sensors 2013, Sections 2-3) and its CSV format."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lasercal.solver.errors import FormatError, LasercalError
from lasercal.solver.formats.fullpose_io import read_circlepoint_csv, write_circlepoint_csv
from lasercal.solver.formats.robots import load_model
from lasercal.solver.identify.circlepoint import (
    CirclePointError,
    circle_point_pose,
    collinear,
    error_statistics,
    farthest_triple,
    fit_circle,
    fit_plane,
    frame_errors,
    plane_frame,
    target_frame,
)
from lasercal.solver.identify.fullpose import default_target, simulate_circlepoint, with_target
from lasercal.solver.kinematics.poe import fk


def arc(R: np.ndarray, centre, radius, angles) -> np.ndarray:
    """Points on a circle in the plane normal to R[:, 2], starting on R[:, 0]."""
    a = np.asarray(angles)
    return centre + radius * (np.cos(a)[:, None] * R[:, 0] + np.sin(a)[:, None] * R[:, 1])


def test_farthest_triple_is_the_papers_p1_p3_p6():
    pts = arc(np.eye(3), np.zeros(3), 100.0, np.radians(20.0 * np.arange(6)))
    i, j, k = farthest_triple(pts)
    assert (i, k) == (0, 5) and j in (2, 3)  # P1, P6 and P3 (or its mirror P4, same area)


def test_plane_and_circle_exact_on_a_steep_plane():
    # a vertical plane: z = Ex + Fy + G cannot describe it in {S}; the paper's frame O1x1y1z1 can
    R = Rotation.from_euler("xyz", [90, 0, 30], degrees=True).as_matrix()
    c = np.array([100.0, -50.0, 300.0])
    pts = arc(R, c, 80.0, np.radians([0, 20, 40, 60, 80, 100]))
    T1 = plane_frame(pts)
    assert np.allclose(T1[:3, :3].T @ T1[:3, :3], np.eye(3), atol=1e-12)
    n, o = fit_plane(pts)
    assert abs(abs(n @ R[:, 2]) - 1) < 1e-12 and abs((o - c) @ R[:, 2]) < 1e-9
    centre, radius = fit_circle(pts, n, o)
    assert np.allclose(centre, c, atol=1e-9) and radius == pytest.approx(80.0, abs=1e-9)


def test_plane_fit_matches_total_least_squares_with_noise():
    rng = np.random.default_rng(3)
    R = Rotation.random(random_state=4).as_matrix()
    pts = arc(R, np.array([10.0, 20.0, 30.0]), 60.0, np.radians(20.0 * np.arange(6))) + rng.normal(
        0, 0.01, (6, 3)
    )
    n, _ = fit_plane(pts)
    tls = np.linalg.svd(pts - pts.mean(0))[2][2]  # the orthogonal-distance plane, an independent fit
    assert (
        np.degrees(np.arccos(min(abs(n @ tls), 1.0))) < 1e-3
    )  # z-only residuals in a near-plane frame ~ orthogonal ones


def test_vectorised_equals_one_by_one():
    rng = np.random.default_rng(0)
    pts = np.stack(
        [
            arc(
                Rotation.random(random_state=s).as_matrix(),
                rng.normal(0, 100, 3),
                50.0,
                np.radians(20.0 * np.arange(6)),
            )
            for s in range(5)
        ]
    )
    pts += rng.normal(0, 0.01, pts.shape)
    T = circle_point_pose(pts)
    for k in range(5):
        assert np.allclose(T[k], circle_point_pose(pts[k]), atol=1e-10)


def test_pose_equals_forward_kinematics_without_noise_and_sense_sets_z():
    puma = load_model("puma560")
    tgt = default_target(puma)
    d = simulate_circlepoint(puma, 10, 6, np.radians(20), 0.0, np.random.default_rng(1), tgt)
    q, T = d.poses()
    Tref = fk(puma.screws, with_target(puma, tgt).ee_pose, q)
    assert np.abs(T - Tref).max() < 1e-9
    R = T[:, :3, :3]
    assert np.allclose(R.transpose(0, 2, 1) @ R, np.eye(3), atol=1e-12) and np.allclose(np.linalg.det(R), 1)
    flipped = circle_point_pose(d.points, -1.0)  # the same points read as a decreasing joint angle
    assert np.allclose(flipped[:, :3, 2], -T[:, :3, 2]) and np.allclose(flipped[:, :3, 0], T[:, :3, 0])


def test_frame_errors_against_scipy_euler_angles():
    rng = np.random.default_rng(2)
    Tref = np.tile(np.eye(4), (4, 1, 1))
    Tref[:, :3, :3] = Rotation.random(4, random_state=5).as_matrix()
    ang = rng.normal(0, 1e-3, (4, 3))
    T = Tref.copy()
    T[:, :3, :3] = Tref[:, :3, :3] @ Rotation.from_euler("xyz", ang).as_matrix()
    T[:, :3, 3] += [[1, 2, 3]]
    dp, de = frame_errors(T, Tref)
    assert np.allclose(dp, [1, 2, 3]) and np.allclose(de, ang, atol=1e-14)


def test_section3_evaluation_is_of_the_papers_order():
    """Puma, g = 30, m = 6 angles in +20 deg steps, N(0, 0.01 mm): Tables 1-2."""
    puma = load_model("puma560")
    tgt = default_target(puma, radius=50.0, offset=50.0)  # the paper does not give its target offset
    d = simulate_circlepoint(puma, 30, 6, np.radians(20), 0.01, np.random.default_rng(2013), tgt)
    q, T = d.poses()
    st = error_statistics(T, fk(puma.screws, with_target(puma, tgt).ee_pose, q))
    # Table 1: means 0.0024 0.0013 0.0036 mm, stds 0.0088 0.0118 0.0086 mm
    assert np.all(np.abs(st["position_mean"]) < 0.008) and np.all(
        (st["position_std"] > 0.005) & (st["position_std"] < 0.02)
    )
    # Table 2: means 0.0074 -3.3e-5 0.0063 deg, stds 0.032 0.0058 0.035 deg
    assert np.all(np.abs(st["euler_mean"]) < 0.03) and np.all(
        (st["euler_std"] > 0.003) & (st["euler_std"] < 0.1)
    )


# ------------------------------------------------------------------ bad input
def test_too_few_points():
    with pytest.raises(CirclePointError, match="at least 3 points"):
        circle_point_pose(np.zeros((4, 2, 3)))


def test_collinear_and_coincident_points():
    line = np.outer(np.arange(6.0), [1.0, 2.0, 3.0])
    good = arc(np.eye(3), np.zeros(3), 10.0, [0, 1, 2])
    assert collinear(np.stack([good, line[:3]])).tolist() == [False, True]
    with pytest.raises(CirclePointError, match=r"collinear \(configuration\(s\) \[1\]"):
        circle_point_pose(np.stack([good, line[:3]]))
    with pytest.raises(CirclePointError, match="collinear"):
        fit_plane(np.ones((5, 3)))
    with pytest.raises(LasercalError):
        circle_point_pose(np.full((3, 3), np.nan))


def test_mismatched_counts():
    pts = arc(np.eye(3), np.zeros(3), 10.0, [0, 1, 2])
    with pytest.raises(CirclePointError, match="one per configuration"):
        fit_circle(np.stack([pts, pts]), np.array([0.0, 0, 1]), np.zeros(3))
    with pytest.raises(CirclePointError, match="3 measured frames but 2"):
        frame_errors(np.tile(np.eye(4), (3, 1, 1)), np.tile(np.eye(4), (2, 1, 1)))
    with pytest.raises(CirclePointError, match="on the joint axis"):
        target_frame(np.array([0, 0, 1.0, 0, 0, 0]), np.array([0, 0, 5.0]))


# ------------------------------------------------------------------ MEASUREMENTS.csv
def sample_csv(tmp_path, g=4, m=4, noise=0.0):
    puma = load_model("puma560")
    d = simulate_circlepoint(puma, g, m, np.radians(20), noise, np.random.default_rng(0))
    path = tmp_path / "m.csv"
    write_circlepoint_csv(path, d, ("a comment",))
    return path, d


def test_csv_round_trip(tmp_path):
    path, d = sample_csv(tmp_path)
    back = read_circlepoint_csv(path, 6)
    assert np.allclose(back.q, d.q, atol=1e-8) and np.allclose(back.points, d.points, atol=1e-5)
    assert back.labels == d.labels and back.lines.tolist() == [3, 7, 11, 15]
    # rows in any order give the same measurement
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:2] + lines[2:][::-1]) + "\n")
    again = read_circlepoint_csv(path)
    assert np.allclose(again.points[::-1], back.points)


def edit(path, line, col, value):
    rows = path.read_text().splitlines()
    header = rows[1].split(",")
    cells = rows[line - 1].split(",")
    cells[header.index(col)] = value
    rows[line - 1] = ",".join(cells)
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize(
    "change, message, line, field",
    [
        (
            lambda p: p.write_text(p.read_text().replace("angle_index", "angle")),
            "missing column 'angle_index'",
            2,
            "angle_index",
        ),
        (lambda p: edit(p, 4, "y", "abc"), "not a number", 4, "y"),
        (lambda p: edit(p, 5, "angle_index", "0"), "angle_index 0 twice", 5, "angle_index"),
        (lambda p: edit(p, 5, "q2", "1.0"), "locked joint q2 moved", 5, "q2"),
        (lambda p: edit(p, 5, "q6", "9.0"), "monotonically", 6, "q6"),
        (
            lambda p: p.write_text(
                "\n".join(ln for i, ln in enumerate(p.read_text().splitlines(), 1) if i not in (4, 5)) + "\n"
            ),
            "2 point(s)",
            3,
            "config",
        ),
        (
            lambda p: p.write_text(
                "\n".join(ln for i, ln in enumerate(p.read_text().splitlines(), 1) if i != 18) + "\n"
            ),
            "has 3 points but 'c001' has 4",
            15,
            "config",
        ),
    ],
)
def test_csv_errors_name_file_line_column(tmp_path, change, message, line, field):
    path, _ = sample_csv(tmp_path)
    change(path)
    with pytest.raises(FormatError) as e:
        read_circlepoint_csv(path)
    assert (
        message in str(e.value)
        and e.value.line == line
        and e.value.field == field
        and str(path) in str(e.value)
    )


def test_csv_collinear_configuration_and_joint_count(tmp_path):
    path, d = sample_csv(tmp_path)
    for k, line in enumerate(range(7, 11)):
        for col, v in zip("xyz", (k, 2 * k, 3 * k)):
            edit(path, line, col, str(float(v)))
    with pytest.raises(FormatError, match="'c002': its points are coincident or collinear") as e:
        read_circlepoint_csv(path)
    assert e.value.line == 7
    path, _ = sample_csv(tmp_path)
    with pytest.raises(FormatError, match="6 joint columns but the robot has 7"):
        read_circlepoint_csv(path, 7)
