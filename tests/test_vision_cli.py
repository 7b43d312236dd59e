"""The vision subcommands end to end: output shapes, bad input, exit codes and messages."""

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import build_parser, main
from lasercal.solver.errors import LasercalError
from lasercal.vision.plane import layout_markers
from lasercal.vision.render import (
    LaserSpot,
    Photo,
    chessboard_print,
    look_down,
    marker_prints,
    marker_sheet,
    pose_view,
    render,
)

VIEW = look_down((1000, 750), 0.3, centre=(450.0, 0.0), yaw_deg=-4, z=-8)
MARKERS = marker_sheet(VIEW, side=40)
PHOTO = dict(paper=0.55, jpeg=92, gamma=2.2, bloom=0.2)
XY = np.array([[431.7, 12.3], [470.2, -25.6]])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("photos")

    def photo(name, xy=(), markers=MARKERS, seed=0):
        spots = tuple(LaserSpot(*VIEW.project(p)[0], 2.0, 3.0, speckle=0.3) for p in xy)
        cv2.imwrite(str(d / name), render(Photo(VIEW, marker_prints(markers), spots, **PHOTO), seed))
        return str(d / name)

    f = {
        "one": photo("one.jpg", XY[:1]),
        "two": photo("two.jpg", XY, seed=1),
        "none": photo("none.jpg", seed=2),
        "few": photo("few.jpg", XY[:1], {i: c for i, c in MARKERS.items() if i == 0}, seed=3),
    }
    (d / "text.jpg").write_text("not an image")
    f["text"] = str(d / "text.jpg")
    f["missing"] = str(d / "missing.jpg")
    layout = d / "layout.yaml"
    layout.write_text(
        yaml.safe_dump(
            {
                "format": "lasercal-layout/1",
                "units": {"length": "mm"},
                "plane": {"z": -8},
                "points": {"P1": [521, 200, -8]},
                "validation": ["P1"],
                "markers": layout_markers("DICT_4X4_50", MARKERS),
            }
        )
    )
    f["layout"] = str(layout)
    f["dir"] = d
    return f


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_spots_json_shape_and_mm(files, capsys):
    code, out, err = run(
        capsys, "spots", files["one"], files["two"], "--layout", files["layout"], "--json", "--expect", "any"
    )
    assert code == 0 and err == ""
    doc = json.loads(out)
    assert [e["image"] for e in doc] == [files["one"], files["two"]]
    for e in doc:
        assert set(e) >= {"image", "spots", "warnings", "error", "plane"} and e["error"] is None
        assert e["plane"]["markers"] == [0, 1, 2, 3] and e["plane"]["rms_mm"] < 0.05
        assert e["plane"]["z_mm"] == -8 and e["plane"]["mm_per_px"] == pytest.approx(0.3, abs=0.003)
        s = e["spots"][0]
        assert set(s) == {
            "u",
            "v",
            "sigma_u",
            "sigma_v",
            "x_mm",
            "y_mm",
            "sigma_x_mm",
            "sigma_y_mm",
            "peak",
            "saturated",
            "area",
            "on_ink",
            "evidence",
        }
    got = np.array([[s["x_mm"], s["y_mm"]] for s in doc[1]["spots"]])
    for p in XY:
        assert np.min(np.hypot(*(got - p).T)) < 0.1
    assert np.hypot(doc[0]["spots"][0]["x_mm"] - XY[0, 0], doc[0]["spots"][0]["y_mm"] - XY[0, 1]) < 0.1


def test_spots_table_and_conventions(files, capsys):
    code, out, _ = run(capsys, "spots", files["one"])
    assert code == 0 and "u_px" in out and files["one"] in out and "opencv convention" in out
    a = json.loads(run(capsys, "spots", files["one"], "--json")[1])[0]["spots"][0]
    b = json.loads(run(capsys, "spots", files["one"], "--json", "--convention", "imagej")[1])[0]["spots"][0]
    assert b["u"] - a["u"] == pytest.approx(0.5) and b["v"] - a["v"] == pytest.approx(0.5)
    assert a["x_mm"] is None
    truth = VIEW.project(XY[0])[0]
    assert np.hypot(a["u"] - truth[0], a["v"] - truth[1]) < 0.2


def test_imagej_method_from_the_command_line(files, capsys):
    code, out, _ = run(
        capsys,
        "spots",
        files["one"],
        "--json",
        "--method",
        "imagej",
        "--imagej-threshold",
        "otsu",
        "--imagej-mode",
        "com",
    )
    s = json.loads(out)[0]
    assert code == 0 and s["method"] == "imagej" and s["spots"][0]["sigma_u"] is None
    truth = VIEW.project(XY[0])[0]
    assert np.hypot(s["spots"][0]["u"] - truth[0], s["spots"][0]["v"] - truth[1]) < 0.5


@pytest.mark.parametrize(
    "key, message",
    [
        ("missing", "missing.jpg: no such file"),
        ("text", "text.jpg: not an image OpenCV can decode"),
        ("none", "none.jpg: no red or green laser spot found"),
        ("two", "two.jpg: 2 spots found where 1 is expected"),
    ],
)
def test_bad_photo_alone_exits_2_with_a_clear_message(files, capsys, key, message):
    code, out, err = run(capsys, "spots", files[key])
    assert code == 2 and message in err and err.startswith("lasercal: error: 1 of 1 photos not measured (")
    assert len(err.splitlines()) == 1 and message in out


def test_a_batch_with_lost_photos_exits_2_naming_them_and_opencv_says_nothing(files, tmp_path):
    """'spots empty.jpg trunc.png good.png': the good photo's spot is printed, the exit code is 2, one
    line names the two lost photos, OpenCV's own '[ WARN:0@...] grfmt_png.cpp' line never shows (a
    process of its own: OpenCV writes to the file descriptor, not to Python's sys.stderr), and no
    overlay is written."""
    good = tmp_path / "good.png"
    cv2.imwrite(str(good), cv2.imread(files["one"]))
    (tmp_path / "empty.jpg").write_bytes(b"")
    (tmp_path / "trunc.png").write_bytes(good.read_bytes()[:3000])
    overlays = tmp_path / "over"
    argv = ["empty.jpg", "trunc.png", "good.png", "--overlay", str(overlays)]
    code = (
        "from lasercal.collector.cli.main import main; import sys; sys.exit(main(['spots', *sys.argv[1:]]))"
    )
    r = subprocess.run([sys.executable, "-c", code, *argv], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 2
    (line,) = r.stderr.splitlines()
    assert line.startswith(
        "lasercal: error: 2 of 3 photos not measured (empty.jpg: not an image OpenCV can decode (JPEG, PNG, "
        "TIFF, ...); trunc.png: the PNG is cut short: 3000 bytes, where its chunks need at least "
    )
    assert "good.png                      1" in r.stdout and not overlays.exists()


def test_missing_markers_exit_2_and_the_batch_goes_on(files, capsys):
    code, out, err = run(capsys, "spots", files["few"], "--layout", files["layout"], "--json")
    assert code == 2 and "few.jpg: found 1 of the 4 markers" in err and "at least 3 needed" in err
    code, out, err = run(
        capsys, "spots", files["few"], files["one"], files["missing"], "--layout", files["layout"], "--json"
    )
    doc = json.loads(out)
    assert code == 2 and [bool(e["spots"]) for e in doc] == [False, True, False]  # the batch went on
    assert "markers" in doc[0]["error"] and doc[0]["warnings"] == [doc[0]["error"]]
    assert err.startswith("lasercal: error: 2 of 3 photos not measured (") and "missing.jpg: no such" in err


def test_command_wide_errors_are_reported_as_errors(files, capsys, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "format: lasercal-layout/1\nmarkers: {dictionary: DICT_4X4_50, ids: {0: [[0, 0], [1, 0]]}}\n"
    )
    code, out, err = run(capsys, "spots", files["one"], "--layout", str(bad))
    assert (
        code == 2
        and err.strip()
        == f"lasercal: error: {bad}, field 'markers.ids.0': expected 4 corners [[x, y], ...] in mm"
    )
    code, _, err = run(capsys, "spots", files["one"], "--reference", files["missing"])
    assert code == 2 and "lasercal spots: error:" in err and "no such file" in err
    code, _, err = run(capsys, "spots", files["one"], "--camera", str(tmp_path / "nocam.yaml"))
    assert code == 2 and "cannot read camera file" in err


def test_reference_median_of_a_series(files, capsys):
    paths = []
    for i, p in enumerate([[440.0, 5.0], [455.0, -12.0], [462.0, 20.0]]):
        spot = (LaserSpot(*VIEW.project(p)[0], 2.0, 1.0),)
        paths.append(str(files["dir"] / f"series{i}.png"))
        cv2.imwrite(paths[-1], render(Photo(VIEW, marker_prints(MARKERS), spot, paper=0.55), 10))
    code, out, _ = run(
        capsys, "spots", *paths, "--reference", "median", "--layout", files["layout"], "--json"
    )
    doc = json.loads(out)
    assert code == 0 and all(len(e["spots"]) == 1 for e in doc)
    assert doc[1]["spots"][0]["x_mm"] == pytest.approx(455.0, abs=0.1)


def test_overlay_png_is_written(files, capsys):
    out_dir = files["dir"] / "overlays"
    code, _, _ = run(
        capsys, "spots", files["two"], "--layout", files["layout"], "--expect", "2", "--overlay", str(out_dir)
    )
    png = cv2.imread(str(out_dir / "two.overlay.png"))
    assert code == 0 and png.shape == (750, 1000, 3)
    original = cv2.imread(files["two"])
    assert np.mean(np.any(png != original, axis=2)) > 0.02  # grid, markers and spots drawn


def test_camera_calibrate_command(files, capsys, tmp_path):
    K = np.array([[600.0, 0, 319.5], [0, 600.0, 239.5], [0, 0, 1]])
    dist = np.array([-0.15, 0.05, 0, 0, 0])
    board = chessboard_print(9, 6, 20.0)
    rng = np.random.default_rng(0)
    paths = []
    for i in range(5):
        R, _ = cv2.Rodrigues(np.r_[rng.uniform(-0.4, 0.4, 2), 0.1])
        t = np.array([*rng.uniform(-50, 50, 2), 450.0]) - R @ np.r_[100.0, 70.0, 0]
        paths.append(str(tmp_path / f"c{i}.png"))
        cv2.imwrite(paths[-1], render(Photo(pose_view((640, 480), K, dist, R, t), (board,), paper=0.7), i))
    out_yaml = tmp_path / "camera.yaml"
    code, out, err = run(
        capsys, "camera-calibrate", *paths, files["text"], "-o", str(out_yaml), "--chessboard", "9x6",
        "--square", "20",
    )  # fmt: skip
    assert code == 2 and "1 of 6 photos unreadable (" in err and "text.jpg: not an image" in err
    assert not out_yaml.exists()  # a photo named and not read fails the batch before anything is written
    code, out, err = run(
        capsys, "camera-calibrate", *paths, "-o", str(out_yaml), "--chessboard", "9x6", "--square", "20"
    )
    assert code == 0 and "from 5 photos" in out
    doc = yaml.safe_load(out_yaml.read_text())
    assert doc["format"] == "lasercal-camera/1" and doc["pattern"]["type"] == "chessboard"
    assert doc["K"][0][0] == pytest.approx(600, rel=0.03) and doc["rms_px"] < 0.2
    code, _, err = run(
        capsys,
        "camera-calibrate",
        files["one"],
        files["none"],
        "-o",
        str(tmp_path / "x.yaml"),
        "--chessboard",
        "9x6",
        "--square",
        "20",
    )
    assert code == 2 and "found in 0 of 2 photos" in err
    code, _, err = run(
        capsys,
        "camera-calibrate",
        files["one"],
        "-o",
        str(tmp_path / "x.yaml"),
        "--charuco",
        "7x5",
        "--square",
        "30",
    )
    assert code == 2 and "--charuco needs --marker" in err


def test_parser_of_the_vision_subcommands():
    parser = build_parser("spots")
    args = parser.parse_args(["spots", "a.jpg", "--color", "green", "--expect", "any", "--imagej-box", "0"])
    assert args.func.__name__ == "spots_command" and args.colour == "green" and args.expect is None
    assert (
        build_parser("beam-check")
        .parse_args(["beam-check", "a", "b", "c", "--laser-length", "350"])
        .laser_length
        == 350
    )
    with pytest.raises(LasercalError, match="argument --expect"):  # one line, not usage + SystemExit
        parser.parse_args(["spots", "a.jpg", "--expect", "0"])


def test_vision_stands_alone():
    code = (
        "import sys, lasercal.vision, lasercal.vision.render, lasercal.vision.overlay; "
        "bad = [m for m in sys.modules if m.split('.')[:2] in (['lasercal', 'solver'], ['lasercal', "
        "'collector'])]; "
        "sys.exit(1 if bad else 0)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
