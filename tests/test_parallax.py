"""Eq. S8 (solver/kinematics/parallax.py): a curled sheet seen through its markers' homography, from where
the camera stands; the session's per-photo camera eyes; the fit that carries it.

Oracles: the ray from the camera through the raised point to the plane, and OpenCV's homography fitted to the
raised markers' corners as the vision fits it (``cv2.findHomography``, least squares); finite differences of
the fit's residual. MuJoCo's own photos of a curled mesh: tests/test_mujoco.py.
"""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest

from lasercal.collector.cli.main import main
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify import spot
from lasercal.solver.kinematics.parallax import parallax_rows, unparallaxed, view_rows

SQUARE = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]])
# eq. S8 against the exact ray and homography, over 2,000 draws of the ranges below (seed 0): at most 2.6 % of
# the largest field (the dropped h / E_z and the homography's second order); the bound is that, rounded up
RELATIVE_BOUND = 0.03


def raised_view(k, eye, corners, s):
    """Where the photo, mapped through the homography fitted to the raised corners, reads the raised points
    s (m, 2) mm: the exact ray s + h (s - E) / (E_z - h) and OpenCV's least-squares homography."""

    def seen(p):
        h = 0.5 * (k[0] * p[:, 0] ** 2 + 2 * k[1] * p[:, 0] * p[:, 1] + k[2] * p[:, 1] ** 2)
        return eye[:2] + (p - eye[:2]) * (eye[2] / (eye[2] - h))[:, None]

    H, _ = cv2.findHomography(seen(corners), corners, 0)
    return cv2.perspectiveTransform(seen(s).reshape(-1, 1, 2), H).reshape(-1, 2)


def draws(n: int, seed: int = 0):
    """Curls up to ~2 mm over an A4 page, a camera 400-900 mm up and up to 400 mm aside, four markers near
    the page's corners, spots between them."""
    rng = np.random.default_rng(seed)
    centres = np.array([[-140.0, -100.0], [120.0, -100.0], [-140.0, 80.0], [120.0, 80.0]])
    for _ in range(n):
        k = rng.uniform(-1.5e-4, 1.5e-4, 3)
        eye = np.r_[rng.uniform(-400, 400, 2), rng.uniform(400, 900)]
        corners = np.concatenate([c + SQUARE for c in centres + rng.uniform(-10, 10, (4, 2))])
        yield k, eye, corners, rng.uniform(-100, 100, (20, 2)) * [1, 0.8]


def test_eq_s8_is_the_ray_through_the_raised_markers_homography():
    """Eq. S8's field matches the exact ray and OpenCV's homography within 3 % of the field (2.6 % measured
    over 2,000 draws); the raw view alone (no homography taking up its plane-like part) is far off."""
    worst, raw = 0.0, 0.0
    for k, eye, corners, s in draws(300):
        exact = raised_view(k, eye, corners, s) - s
        model = parallax_rows(s, np.repeat(eye[None], len(s), 0), corners) @ k
        field = np.abs(exact).max()
        worst = max(worst, np.abs(exact - model).max() / field)
        raw = max(raw, np.abs(exact - view_rows(s, np.repeat(eye[None], len(s), 0)) @ k).max() / field)
    assert worst < RELATIVE_BOUND, worst
    assert raw > 0.5, raw  # the homography's share is most of the raw view: the test sees it


def test_unparallaxed_undoes_eq_s8():
    """A spot moved by eq. S8's field comes back to where it was, to 1e-9 mm."""
    for k, eye, corners, s in draws(50, seed=1):
        seen = s[0] + parallax_rows(s[:1], eye[None], corners)[0] @ k
        assert np.abs(unparallaxed(seen, eye, k, corners) - s[0]).max() < 1e-9


def _camera_session(tmp_path, eyes=None):
    """The solver's simulated sheet session, every spot measured, with ``eyes`` (m, 3) written as the
    camera_eye_x .. columns (cells as given, strings allowed)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    out = tmp_path / "s"
    args = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--sheet-pose", "5", "-3", "1.5"]
    assert main([*args, "--per-point", "4", "--measured", "1", "--seed", "2", "-o", str(out)]) == 0
    if eyes is not None:
        path = out / "captures.csv"
        lines = path.read_text().splitlines(keepends=True)
        head = [i for i, ln in enumerate(lines) if not ln.startswith("#")][0]
        rows = list(csv.reader(lines[head:]))
        rows[0] += ["camera_eye_x", "camera_eye_y", "camera_eye_z"]
        for r, e in zip(rows[1:], eyes):
            r += [str(v) for v in e]
        with open(path, "w", newline="") as f:
            f.writelines(lines[:head])
            csv.writer(f, lineterminator="\n").writerows(rows)
    return out


def test_a_session_reads_each_photos_eye_and_names_a_torn_cell(tmp_path):
    """captures.csv's camera_eye_x .. columns load as (m, 3) mm, kept by a subset; a cell torn or a camera
    under the sheet is refused naming the file, the line and the column."""
    m = len(load_session(_camera_session(tmp_path / "a")).q)
    eyes = np.c_[np.full(m, 350.0), np.linspace(-5, 5, m), np.full(m, 600.0)]
    s = load_session(_camera_session(tmp_path / "b", eyes))
    np.testing.assert_allclose(s.camera_eye, eyes)
    np.testing.assert_allclose(s.subset(np.arange(m) % 2 == 0).camera_eye, eyes[::2])
    for cell, field in (("", "camera_eye_y"), ("x", "camera_eye_y"), ("-3", "camera_eye_z")):
        bad = eyes.astype(object)
        bad[3, 1 if field.endswith("y") else 2] = cell
        folder = _camera_session(tmp_path / f"bad{len(cell)}{field}", bad)
        with pytest.raises(FormatError) as e:
            load_session(folder)
        assert e.value.field == field and e.value.line is not None and "captures.csv" in str(e.value)


def test_the_fit_with_eq_s8_has_the_jacobian_of_its_residual(tmp_path, monkeypatch):
    """The shaped fit of a session whose photos told their camera carries eq. S8 on the curl's terms (no
    free warp); its Jacobian matches central differences of its residual."""
    m = len(load_session(_camera_session(tmp_path / "a")).q)
    rng = np.random.default_rng(0)
    eyes = np.c_[rng.uniform(300, 400, m), rng.uniform(-50, 50, m), rng.uniform(550, 650, m)]
    session = load_session(_camera_session(tmp_path / "b", eyes))
    corners = np.concatenate([c + SQUARE for c in ([-140, -100], [120, -100], [-140, 80], [120, 80])])
    monkeypatch.setattr(spot, "marker_corners", lambda s: corners.reshape(-1, 4, 2))
    prob = spot.spot_problem(session, session.robot, None, shape=True)
    assert prob.V is not None and prob.nw == 0
    v = prob.u0[prob.free] + rng.normal(0, 1e-3, len(prob.free))
    for name, value in (("sheet.kxx", 2e-4), ("sheet.kxy", -1e-4), ("sheet.kyy", 3e-4)):  # a few mm of curl
        v[prob.names.index(name)] = value
    J = prob.jacobian(v)
    for j in range(len(v)):
        step = 1e-6 * max(1.0, abs(v[j]))
        up, down = v.copy(), v.copy()
        up[j] += step
        down[j] -= step
        fd = (prob.residual(up) - prob.residual(down)) / (2 * step)
        np.testing.assert_allclose(
            J[:, :, j], fd, atol=2e-6 * max(1.0, np.abs(fd).max()), err_msg=prob.names[j]
        )
