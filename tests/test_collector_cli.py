"""``lasercal capture`` / ``lasercal validate`` end to end: kill-and-resume, bad input, missing extras,
validation photos."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.collector.errors import DeviceError
from lasercal.collector.sessions.validate import OpenCVCamera
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.spot import predict_spots

ROOT = Path(__file__).resolve().parents[1]
THESIS = str(builtin_dir("layouts") / "thesis.yaml")
TRUTH = load_model("panda_thesis_identified")
AUTO = ["capture", "--layout", THESIS, "--backend", "fake", "--per-point", "4", "--seed", "3", "--auto"]


def _complete_rows(path: Path) -> list[list[str]]:
    lines = path.read_bytes().split(b"\n")[1:-1]  # header, ..., and whatever follows the last newline
    return [ln.decode().split(",") for ln in lines]


def test_killed_at_random_moments_the_session_resumes_to_exactly_the_uninterrupted_one(tmp_path, capsys):
    assert main(AUTO + ["-o", str(tmp_path / "ref")]) == 0
    ref = _complete_rows(tmp_path / "ref" / "captures.csv")
    folder = tmp_path / "s"
    pace = ["--auto-pace", "0.05"]
    runs = [
        AUTO + pace + ["-o", str(folder)],
        ["capture", "--resume", str(folder), "--auto"] + pace,
        ["capture", "--resume", str(folder), "--auto"] + pace,
    ]
    rng = np.random.default_rng(1)
    kept = []
    for argv, at in zip(runs, (2, 5, 8)):
        child = subprocess.Popen(
            [sys.executable, "-m", "lasercal.collector.cli.main"] + argv,
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        end = time.monotonic() + 60
        while (
            len(_complete_rows(folder / "captures.csv")) < at if (folder / "captures.csv").exists() else True
        ):
            assert child.poll() is None, child.stderr.read().decode()
            assert time.monotonic() < end
            time.sleep(0.005)
        time.sleep(rng.uniform(0, 0.05))  # somewhere inside the next capture
        child.kill()
        child.wait()
        child.stderr.close()
        rows = _complete_rows(folder / "captures.csv")
        assert rows == ref[: len(rows)]  # every complete row is intact and as it would have been
        kept.append(len(rows))
    assert main(["capture", "--resume", str(folder), "--auto"]) == 0
    assert "resuming" in capsys.readouterr().out
    s, r = load_session(folder), load_session(tmp_path / "ref")
    assert list(s.point) == list(r.point) and kept[-1] < s.m == 12
    np.testing.assert_array_equal(s.q, r.q)
    assert np.all(np.diff(s.t) > 0)


def test_malformed_layout_is_one_line_naming_file_and_field(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: lasercal-layout/1\nplane: {z: -8}\npoints:\n  P1: [521, 200]\n")
    assert (
        main(
            [
                "capture",
                "--layout",
                str(bad),
                "--backend",
                "fake",
                "--per-point",
                "3",
                "--auto",
                "-o",
                str(tmp_path / "s"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"lasercal: error: {bad}, field 'points.P1':") and "\n" not in err
    bad.write_text("points: {P1: [1, 2, 3]\n")
    assert (
        main(
            [
                "capture",
                "--layout",
                str(bad),
                "--backend",
                "fake",
                "--per-point",
                "3",
                "--auto",
                "-o",
                str(tmp_path / "s"),
            ]
        )
        == 2
    )
    assert f"{bad}, line" in capsys.readouterr().err


def test_session_options_are_checked(tmp_path, capsys):
    assert main(["capture", "--layout", THESIS, "--per-point", "3", "-o", str(tmp_path / "s")]) == 2
    assert "a new session needs --backend" in capsys.readouterr().err
    assert (
        main(
            [
                "capture",
                "--layout",
                THESIS,
                "--backend",
                "franky",
                "--host",
                "127.0.0.1",
                "--per-point",
                "3",
                "--auto",
                "-o",
                str(tmp_path / "s"),
            ]
        )
        == 2
    )
    assert "--auto needs --backend fake" in capsys.readouterr().err
    assert main(AUTO + ["-o", str(tmp_path / "s")]) == 0
    assert main(AUTO + ["-o", str(tmp_path / "s")]) == 2
    assert "resume it with --resume" in capsys.readouterr().err
    assert main(["capture", "--resume", str(tmp_path / "s"), "--per-point", "5", "--auto"]) == 2
    assert "was started with per-point 4: it cannot change on resume" in capsys.readouterr().err
    assert (
        main(["capture", "--resume", str(tmp_path / "s"), "--auto"]) == 0
    )  # complete already: nothing to do
    assert load_session(tmp_path / "s").m == 12


@pytest.mark.parametrize(
    "backend, module, extra, package",
    [
        ("franky", "franky", "franky", "franky-control"),
        ("panda-py", "panda_py", "panda", "panda-python"),
        ("ros", "roslibpy", "ros", "roslibpy"),
    ],
)
def test_missing_robot_sdk_is_one_line_with_the_pip_command(
    tmp_path, capsys, monkeypatch, backend, module, extra, package
):
    monkeypatch.setitem(sys.modules, module, None)  # as if not installed
    argv = [
        "capture",
        "--layout",
        THESIS,
        "--backend",
        backend,
        "--host",
        "127.0.0.1",
        "--per-point",
        "3",
        "-o",
        str(tmp_path / "s"),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        f"lasercal: error: the {backend} backend needs the Python package {package}, which is not installed: "
        f"pip install 'lasercal[{extra}]' (or pip install {package})"
    )
    assert not (tmp_path / "s").exists()  # nothing to clean up before trying again


def test_validate_fake_photos_measure_the_true_spots(tmp_path, capsys):
    assert (
        main(
            ["validate", "panda", "--point", "P4", "-n", "5", "--backend", "fake", "-o", str(tmp_path / "v")]
        )
        == 0
    )
    out = capsys.readouterr().out
    meta = yaml.safe_load((tmp_path / "v" / "validation.yaml").read_text())
    assert (
        meta["format"] == "lasercal-validation/1"
        and meta["units"]["q"] == "rad"
        and meta["motion"] == "moved by the backend"
    )
    lines = (tmp_path / "v" / "validation.csv").read_text().splitlines()
    assert lines[0].startswith("# ") and lines[1] == "index,q1,q2,q3,q4,q5,q6,q7,photo,x_mm,y_mm,q_dev"
    rows = [ln.split(",") for ln in lines[2:]]
    assert len(rows) == 5 and all((tmp_path / "v" / r[8]).is_file() for r in rows)
    q = np.array([[float(v) for v in r[1:8]] for r in rows])
    measured = np.array([[float(r[9]), float(r[10])] for r in rows])
    true_spots, _ = predict_spots(TRUTH, q, -8.0)  # where the fake robot's beam really was, at the logged q
    assert np.abs(measured - true_spots[:, :2]).max() < 0.05
    err = np.linalg.norm(measured - [441, 160], axis=1)
    assert err.mean() > 3  # the nominal model misses P4 by millimetres (thesis: 9.76 mm mean)
    assert "P4: 5 spots measured" in out
    assert (
        main(["validate", "panda", "-n", "5", "--backend", "fake", "-o", str(tmp_path / "v")]) == 2
    )  # never overwritten
    assert "exists and is kept (resume it with --resume" in capsys.readouterr().err
    # the true geometry as the model under test: the spots land on P4 up to the standstill residue
    assert (
        main(
            [
                "validate",
                str(builtin_dir("robots") / "panda_thesis_identified.yaml"),
                "-n",
                "3",
                "--backend",
                "fake",
                "--guide",
                "-o",
                str(tmp_path / "t"),
            ]
        )
        == 0
    )
    rows = [ln.split(",") for ln in (tmp_path / "t" / "validation.csv").read_text().splitlines()[2:]]
    assert (
        np.linalg.norm(np.array([[float(r[9]), float(r[10])] for r in rows]) - [441, 160], axis=1).max() < 0.5
    )
    assert (
        yaml.safe_load((tmp_path / "t" / "validation.yaml").read_text())["motion"] == "guided by the operator"
    )


def test_opencv_camera_reads_a_capture_device(tmp_path):
    for i in range(6):
        cv2.imwrite(str(tmp_path / f"{i:04d}.png"), np.full((24, 32, 3), 40 * i, np.uint8))
    cam = OpenCVCamera(str(tmp_path / "%04d.png"), flush=1)
    assert cam.photo().mean() == 40  # frame 0 dropped: drivers hand out stale frames first
    assert cam.photo().mean() == 120
    cam.close()
    with pytest.raises(DeviceError, match="cannot open"):
        OpenCVCamera(str(tmp_path / "none%04d.png"))


def test_photos_of_a_layout_with_markers_are_measured_through_vision(tmp_path):
    from lasercal.collector.sessions.validate import measure_with_markers
    from lasercal.collector.worlds.cameras import fake_view
    from lasercal.vision.plane import load_markers
    from lasercal.vision.render import LaserSpot, Photo, aruco_print, render, square_corners

    centres = {0: (401, 200), 1: (481, 200), 2: (481, 120), 3: (401, 120)}  # around P4 = (441, 160), mm
    corners = {i: square_corners(c, 20.0) for i, c in centres.items()}
    layout = tmp_path / "markers.yaml"
    layout.write_text(
        yaml.safe_dump(
            {
                "format": "lasercal-layout/1",
                "plane": {"z": -8},
                "points": {"P4": [441, 160, -8]},
                "markers": {"dictionary": "DICT_4X4_50", "ids": {i: c.tolist() for i, c in corners.items()}},
            }
        )
    )
    view = fake_view((441, 160), -8.0)
    spot = np.array([443.7, 158.2])
    u, v = view.project(spot)[0]
    prints = tuple(aruco_print("DICT_4X4_50", i, c) for i, c in corners.items())
    img = render(Photo(view, prints, (LaserSpot(u, v, 2.5, 0.8, 0.2),)), seed=3)
    xy, _ = measure_with_markers(img, "photo", load_markers(layout))
    assert np.abs(xy - spot).max() < 0.05


def test_validation_photos_carry_the_exposure_advice_while_they_are_taken():
    """Issue 13: an overexposed phone photo is measured and its one-line advice reaches the operator."""
    from lasercal.collector.sessions.validate import measure_known_view
    from lasercal.vision.render import PhoneCamera, Photo, look_down, render, tilted_spot

    view = look_down((200, 160), 0.3, centre=(450.0, 0.0))
    truth = view.unproject(np.array([[100.3, 80.6]]))[0]
    over = render(Photo(view, spots=(tilted_spot(100.3, 80.6, 4.0, 30.0, 0, 0, speckle=0),),
                        camera=PhoneCamera()), 0)  # fmt: skip
    xy, advice = measure_known_view(over, "over.png", view)
    assert np.hypot(*(xy - truth)) < 0.3 and advice and "clipped" in advice and "exposure" in advice
    fine = render(Photo(view, spots=(tilted_spot(100.3, 80.6, 2.0, 0.8, 0, 0, speckle=0),),
                        camera=PhoneCamera()), 0)  # fmt: skip
    assert measure_known_view(fine, "fine.png", view)[1] is None
