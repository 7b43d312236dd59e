"""Issue 52 item 2: a sheet that is not flat and a printer's shear (eqs. S5, S6 of solver.kinematics.sheet),
the camera's view of the raised paper (eq. S7 of solver.identify.spot), and the data's decision to keep them
(solver.identify.sheetshape). Units: mm, rad; curvatures 1/mm."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.collector.cli.main import main
from lasercal.collector.worlds import fakeworld
from lasercal.collector.worlds.truesheet import PaperSheet
from lasercal.solver.formats.robots import load_model, model_from_dict
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.sheetshape import curl_range, decide_sheet_shape
from lasercal.solver.identify.spot import camera_warp_rows
from lasercal.solver.kinematics.sheet import SheetPose, sheet_to_base

V = np.array([452.0, 3.0, 0.02, 1.2e-3, -0.8e-3, 3e-3, -1.5e-3, 1.1e-3, -4e-5, 2e-5, -1.6e-4])


def test_print_shear_and_height_field_against_a_direct_construction():
    """Eqs. S5, S6 built by hand (a print matrix, scipy's rotation, the quadratic form s^T K s / 2) and by
    sheet_to_base; its Jacobian against central differences; the height's Hessian by finite differences is
    K (a cylinder: kyy alone; a dome: kxx = kyy)."""
    rng = np.random.default_rng(0)
    uv = rng.uniform(-140, 140, (50, 2))
    z = rng.uniform(-9, -7, 50)
    x, y, yaw, ex, ey, tx, ty, g, kxx, kxy, kyy = V
    printed = uv @ np.array([[1 + ex, g], [0.0, 1 + ey]]).T  # eq. S5 as a matrix
    K = np.array([[kxx, kxy], [kxy, kyy]])
    R = Rotation.from_euler("z", yaw).as_matrix()[:2, :2]
    expected = np.column_stack(
        [printed @ R.T + [x, y], z + printed @ [tx, ty] + 0.5 * np.einsum("ki,ij,kj->k", printed, K, printed)]
    )
    p, J = sheet_to_base(V, uv, z)
    assert np.abs(p - expected).max() < 1e-10
    for i in range(len(V)):
        h = 1e-6 * max(1.0, abs(V[i]))
        e = np.zeros(len(V))
        e[i] = h
        fd = (sheet_to_base(V + e, uv, z)[0] - sheet_to_base(V - e, uv, z)[0]) / (2 * h)
        assert np.abs(J[:, :, i] - fd).max() < 1e-6 * max(1.0, np.abs(fd).max()), i
    for k in ([0.0, 0.0, -2e-4], [1e-4, 0.0, 1e-4], [3e-5, -2e-5, 7e-5]):  # cylinder, dome, saddle-ish
        pose = SheetPose(450.0, 0.0, 5.0, curl_xx_per_mm=k[0], curl_xy_per_mm=k[1], curl_yy_per_mm=k[2])
        d = 0.5
        hess = np.zeros((2, 2))
        for a in range(2):
            for b in range(2):
                ea, eb = np.eye(2)[a] * d, np.eye(2)[b] * d
                f = [
                    pose.to_base(np.array([[20.0, -30.0]]) + sa * ea + sb * eb, 0.0)[0, 2]
                    for sa, sb in ((1, 1), (1, -1), (-1, 1), (-1, -1))
                ]
                hess[a, b] = (f[0] - f[1] - f[2] + f[3]) / (4 * d * d)
        assert np.allclose(hess, [[k[0], k[1]], [k[1], k[2]]], atol=1e-9), (hess, k)
    cyl = SheetPose(curl_yy_per_mm=-2e-4)  # h = -1e-4 v^2: over v in [-100, 100] it spans 1 mm
    assert abs(curl_range(cyl, np.array([[-50.0, -100.0], [50.0, 100.0]])) - 1.0) < 1e-9


def test_the_print_map_is_the_fake_worlds_and_from_base_inverts_it():
    """Eq. S5 against the fake world's own eq. W1 (collector.worlds.truesheet: a = s_x u + g' s_y v, b = s_y
    v, its skew g' = g / s_y), and from_base against its inverse (printed)."""
    pose = SheetPose.from_vector(V)
    paper = PaperSheet(np.zeros(3), 0.0, np.array([pose.scale_x, pose.scale_y]), pose.shear / pose.scale_y)
    uv = np.random.default_rng(1).uniform(-140, 140, (30, 2))
    flat = SheetPose.from_vector(np.r_[0.0, 0.0, 0.0, V[3:5], 0.0, 0.0, V[7]])  # no turn, no tilt, no curl
    assert np.abs(flat.to_base(uv, 0.0)[:, :2] - paper.on_paper(uv)).max() < 1e-10
    assert np.abs(pose.from_base(pose.to_base(uv, -8.0)) - uv).max() < 1e-9
    assert (
        np.abs(
            flat.from_base(np.c_[paper.on_paper(uv), np.zeros(30)]) - paper.printed(paper.on_paper(uv))
        ).max()
        < 1e-9
    )


def test_the_camera_warp_vanishes_at_its_anchors_and_is_quadratic_between():
    """Eq. S7: the field is zero at the markers (an affine part taken out there), aimed captures have none,
    and its second differences are the quadratic's."""
    anchors = np.array([[80, 123.5], [80, 0], [80, -123.5], [-80, -123.5], [-80, 0], [-80, 123.5]])
    W = camera_warp_rows(anchors, np.ones(6, bool), anchors)
    a = np.array([1e-4, -3e-5, 2e-4, 0.0, 5e-5, -1e-4])
    field = W @ a
    # an affine fit to a quadratic at 6 points is exact only where the quadratic is affine: check the mean
    assert np.abs(field.mean(axis=0)).max() < 1e-12
    uv = np.array([[0.0, 0.0], [10.0, 0.0], [-10.0, 0.0]])
    f = camera_warp_rows(uv, np.ones(3, bool), anchors) @ a
    assert np.allclose((f[1] + f[2] - 2 * f[0]) / 100.0, [a[0], a[3]])
    assert np.all(camera_warp_rows(uv, np.zeros(3, bool), anchors) == 0)


def test_model_files_carry_the_shape_and_old_ones_load_flat(tmp_path):
    """A shaped sheet round-trips through the model file's ``sheet`` mapping; a file without the new keys is
    a flat, square sheet."""
    model = load_model("panda").replace(sheet=SheetPose.from_vector(V))
    model.save(tmp_path / "m.yaml")
    back = load_model(tmp_path / "m.yaml").sheet
    assert back.shaped and np.allclose(back.full_vector, V, rtol=1e-9, atol=1e-12)
    d = model.to_dict()
    for k in ("shear", "curl_xx_per_mm", "curl_xy_per_mm", "curl_yy_per_mm"):
        d["sheet"].pop(k)
    old = model_from_dict(d).sheet
    assert not old.shaped and old.height(np.array([[100.0, 100.0]]))[0] == 0.0


def _camera_session(tmp_path, effects: str, bulge=None):
    """A fake-world camera session (30 captures beside the crosses, no coach: quick), its flat fit."""
    assert main(["sheet", "-o", str(tmp_path / "sheet"), "--place", "450", "0", "0"]) == 0
    saved = fakeworld.PAPER_BULGE_MM
    if (
        bulge is not None
    ):  # the outside world curls its paper by 1.4-1.9 mm (the fake world's: 0.1-0.3)
        fakeworld.PAPER_BULGE_MM = bulge
    try:
        argv = ["capture", "--layout", str(tmp_path / "sheet" / "layout.yaml"), "--robot", "panda"]
        argv += ["--backend", "fake", "--auto", "--per-point", "6", "--aim-noise", "3", "--camera", "fake"]
        argv += ["--no-coach", "--aim", "cross", "--seed", "3", "--photos", "none", "--effects", effects]
        assert main([*argv, "-o", str(tmp_path / "s")]) == 0
    finally:
        fakeworld.PAPER_BULGE_MM = saved
    session = load_session(tmp_path / "s")
    return session, fit(session)


def test_a_curled_paper_is_named_and_modelled(tmp_path):
    """paper-curl on (1.4-1.9 mm): the shape is kept (F test and held out), its curl is a mm or two, and the
    fit's residual on the sheet drops (in-sample and held out)."""
    session, flat = _camera_session(tmp_path, "repeatability,paper-curl", (1.4, 1.9))
    shape = decide_sheet_shape(session, flat)
    print(shape.as_dict())
    assert shape.kept, shape.reason
    assert shape.p < 1e-4 and shape.holdout["gain_percent"] > 30
    assert 0.8 < shape.curl_mm < 3.0
    assert shape.holdout["shaped_mm"] < 0.6 * shape.holdout["flat_mm"]
    assert shape.shaped.rms_mm < 0.6 * flat.rms_mm


def test_a_flat_paper_is_not_named(tmp_path):
    """A flat, square print on a sloping table (eq. S3 holds it all): the shape is not kept."""
    session, flat = _camera_session(tmp_path, "repeatability,print-scale,table-slope")
    shape = decide_sheet_shape(session, flat)
    print(shape.as_dict())
    assert shape.tested and not shape.kept, shape.reason


def test_the_finding_names_the_sheet_and_where_structure_remains():
    """The finding line names the sheet (never a joint); not kept, residual structure beyond the noise is
    given by its size and cell, not as 0.000."""
    from lasercal.collector.report.text import sheet_shape_line

    kept = {
        "tested": True,
        "kept": True,
        "F": 27.8,
        "p_value": 1.8e-12,
        "curl_mm": 1.6,
        "shear_mm_per_m": -0.4,
        "holdout": {"flat_mm": 0.59, "shaped_mm": 0.14},
        "reason": "",
        "camera_warp_mm": 0.0,
    }
    line = sheet_shape_line(kept)
    assert line.startswith(
        "finding (the sheet): not flat -- curl 1.60 mm over the sheet, shear 0.40 mm per m"
    )
    assert "joint" not in line
    cells = {"x0 y0": {"n": 5, "mean_mm": [0.3, 0.4]}, "x- y-": {"n": 5, "mean_mm": [0.0, 0.01]}}
    flat = {
        **kept,
        "kept": False,
        "reason": "not significant",
        "F": 2.0,
        "p_value": 0.05,
        "regions": {"cells": cells, "p": 0.001, "structure_mm": 0.145, "worst": "x0 y0"},
    }
    line = sheet_shape_line(flat)
    assert "0.145 mm RMS" in line and "x0 y0 (0.500 mm)" in line and "0.000" not in line
    assert "beyond their noise" not in sheet_shape_line({**flat, "regions": {**flat["regions"], "p": 0.5}})
    # no F test (the data cannot see a shape): its reason said once, not twice
    blind = {
        **flat,
        "F": None,
        "reason": "the data cannot see the sheet's shape beyond its plane",
        "regions": {},
    }
    assert sheet_shape_line(blind) == (
        "finding (the sheet): flat and square within what the data see (the data cannot see the sheet's "
        "shape beyond its plane)"
    )
