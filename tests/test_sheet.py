"""Issue 23, the printed sheet: `lasercal sheet`'s print round trip (every marker and cross found at its
layout position within 0.1 mm in the rasterised PDF, and in the SVG's own paths), the layout it writes, the
reach check, and a phone photo of the sheet measured in sheet (and through a sheet pose, base) mm.

The measuring code (PDF raster, cross locator, phone photo of the sheet) is benchmarks/bench_sheet.py's,
which prints the same figures over more papers and photos.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout
from lasercal.solver.kinematics.sheet import SheetPose
from lasercal.vision.plane import load_markers
from lasercal.vision.sheet import design_sheet, page_to_sheet, sheet_to_page

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from bench_sheet import pdf_round_trip, sheet_photo, svg_round_trip  # noqa: E402

PAPERS = ("A4", "A3", "letter")


@pytest.fixture(scope="module")
def sheets(tmp_path_factory):
    """paper -> (design, folder) written by the command, default options (plane z -8 mm, no placement)."""
    out = {}
    for paper in PAPERS:
        folder = tmp_path_factory.mktemp("sheet") / paper
        assert main(["sheet", "-o", str(folder), "--paper", paper]) == 0
        out[paper] = (design_sheet(paper), folder)
    return out


@pytest.mark.parametrize("paper", PAPERS)
def test_printed_pdf_shows_every_marker_and_cross_at_its_layout_position(sheets, paper):
    pytest.importorskip("pypdfium2")
    design, folder = sheets[paper]
    rt = pdf_round_trip(folder / "sheet.pdf", folder / "layout.yaml", design, dpi=200)
    assert rt.page_error < 0.01  # 1:1: the page is the paper
    assert rt.markers_found == rt.markers >= 6
    # measured 0.0007 mm (corners) and 0.0044 mm (crosses) at 200 dpi, 0.127 mm/px
    assert rt.marker_max < 0.1 and rt.cross_max < 0.1 and rt.cross_homography_max < 0.1


@pytest.mark.parametrize("paper", PAPERS)
def test_svg_paths_are_the_layout_and_its_markers_decode(sheets, paper):
    design, folder = sheets[paper]
    rt = svg_round_trip(folder / "sheet.svg", folder / "layout.yaml", design)
    assert rt.page_error < 0.01 and rt.markers_found == rt.markers
    assert rt.marker_max < 0.1 and rt.cross_max < 0.01


def test_the_page_and_sheet_frames_are_one_right_handed_frame():
    # eq. P1: x up the page, y to the left; z = x cross y comes out of the paper
    uv = np.array([[10.0, 20.0], [200.0, 5.0]])
    xy = page_to_sheet(uv, 297, 210)
    assert np.allclose(xy, [[20 - 105, 148.5 - 10], [5 - 105, 148.5 - 200]])
    assert np.allclose(sheet_to_page(xy, 297, 210), uv)
    up, left = page_to_sheet([[148.5, 106], [147.5, 105]], 297, 210)
    assert np.allclose(up, [1, 0]) and np.allclose(left, [0, 1])


def test_layout_describes_the_sheet_in_its_own_frame(sheets):
    design, folder = sheets["A4"]
    lay = load_layout(folder / "layout.yaml")  # the solver's reader: frame, plane, points, roles
    assert lay.frame == "sheet" and lay.plane_z == -8 and lay.sheet is None
    assert lay.calibration == ("P1", "P2", "P3", "P4", "P5") and lay.validation == ("P6", "P7")
    xyz = np.array([lay.points[n] for n in lay.calibration])
    assert np.all(xyz[:, 2] == 0)
    assert np.allclose(xyz[:, :2], [design.points[n] for n in lay.calibration])
    # spread: the calibration points span a rectangle, not a line
    assert np.ptp(xyz[:, 0]) >= 60 and np.ptp(xyz[:, 1]) >= 150
    assert np.linalg.matrix_rank(xyz[1:, :2] - xyz[0, :2]) == 2
    # every point lies inside the markers' hull: its spot is interpolated, not extrapolated
    markers = load_markers(folder / "layout.yaml")
    assert markers.frame == "sheet" and len(markers.corners) == 6
    hull = cv2.convexHull(np.concatenate(list(markers.corners.values())).astype(np.float32))
    inside = [cv2.pointPolygonTest(hull, (float(x), float(y)), True) for x, y in design.points.values()]
    assert min(inside) > 20
    text = (folder / "layout.yaml").read_text()
    assert "frame: sheet" in text and "mm" in text.splitlines()[1]  # after the whole-file line
    assert text.startswith("# whole file") and text.endswith("\n...\n")  # solver/whole.py


def test_placement_and_reach_check(tmp_path, capsys):
    out = tmp_path / "placed"
    assert main(["sheet", "-o", str(out), "--robot", "panda", "--place", "450", "20", "10"]) == 0
    printed = capsys.readouterr().out
    assert "panda can aim its beam at every point" in printed and printed.count(" ok") == 7
    lay = load_layout(out / "layout.yaml")
    assert lay.sheet == SheetPose(450.0, 20.0, 10.0)
    base = lay.in_base()  # eq. S1 through the rough placement
    assert np.allclose(base.points["P3"], [450, 20, -8])
    c, s = np.cos(np.radians(10)), np.sin(np.radians(10))
    x, y = lay.points["P1"][:2]
    assert np.allclose(base.points["P1"], [450 + c * x - s * y, 20 + s * x + c * y, -8])


def test_points_beyond_the_reach_are_named_and_nothing_is_written(tmp_path, capsys):
    out = tmp_path / "far"
    assert main(["sheet", "-o", str(out), "--robot", "panda", "--place", "1300", "0", "90"]) == 2
    err = capsys.readouterr().err.strip()  # yaw 90: the sheet's y runs along the base's -x
    assert (
        len(err.splitlines()) == 1
        and "panda cannot aim its beam at P1 at (1218, 31) mm, P2 at (1382, 31)" in err
    )
    assert not out.exists()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--paper", "A5"], "argument --paper: paper 'A5': expected A4, A3, letter or WxH"),
        (["--paper", "150x150"], "is too small"),
        (["--margin", "-1"], "argument --margin"),
        (["--robot", "panda"], "give --place X Y YAW"),
    ],
)
def test_bad_sheet_options_give_one_line(tmp_path, capsys, argv, message):
    assert main(["sheet", "-o", str(tmp_path / "s"), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err


def test_phone_photo_of_the_sheet_measured_in_sheet_and_base_mm(sheets, tmp_path, capsys):
    design, folder = sheets["A4"]
    layout = folder / "layout.yaml"
    img, xy, _ = sheet_photo(load_markers(layout), design.points, "P6", seed=3)
    photo = tmp_path / "p6.png"
    cv2.imwrite(str(photo), img)  # the phone's 4:2:0 JPEG, decoded: measured on the luma as a JPEG is
    argv = ["spots", str(photo), "--layout", str(layout), "--channel", "luma"]
    assert main([*argv, "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)[0]
    spot = entry["spots"][0]
    assert entry["frame"] == "sheet"
    error = np.hypot(spot["x_mm"] - xy[0], spot["y_mm"] - xy[1])
    assert error < 0.15  # benchmarks/bench_sheet.py: 0.04 mm RMS per axis over 40 photos

    # Through an identified sheet pose (eq. S1) to the base frame: a model file carrying one.
    pose = SheetPose(452.3, -7.1, 3.5)
    model = tmp_path / "m.yaml"
    load_model("panda").replace(sheet=pose).save(model)
    assert main([*argv, "--json", "--model", str(model)]) == 0
    spot = json.loads(capsys.readouterr().out)[0]["spots"][0]
    truth = pose.to_base(xy[None], -8)[0]
    assert np.hypot(spot["x_base_mm"] - truth[0], spot["y_base_mm"] - truth[1]) < 0.15
    assert main([*argv, "--model", str(model)]) == 0
    table = capsys.readouterr().out.splitlines()
    assert f"mm: sheet frame on the plane; bx_mm, by_mm: base frame through {model}" in table[0]
    assert table[1].split()[-2:] == ["bx_mm", "by_mm"]
    assert float(table[2].split()[-2]) == pytest.approx(spot["x_base_mm"], abs=1e-3)


def test_model_without_a_sheet_pose_or_a_base_layout_is_refused(sheets, tmp_path, capsys):
    design, folder = sheets["A4"]
    photo = tmp_path / "x.png"
    cv2.imwrite(str(photo), np.full((100, 100, 3), 128, np.uint8))
    assert main(["spots", str(photo), "--layout", str(folder / "layout.yaml"), "--model", "panda"]) == 2
    assert "panda: no 'sheet' pose" in capsys.readouterr().err
    base = tmp_path / "base.yaml"
    doc = yaml.safe_load((folder / "layout.yaml").read_text())
    doc.pop("frame")
    base.write_text(yaml.safe_dump(doc))
    assert main(["spots", str(photo), "--layout", str(base), "--model", "panda"]) == 2
    assert "it needs --layout with 'frame: sheet'" in capsys.readouterr().err
