"""Photos that fit a laptop (issue 45 item 6): a session says what its photos take (an estimate after its
first photo, the size at its end) and keeps fewer or smaller ones on request -- without losing any
measurement: the spots and sigmas in the CSV are those of the session that keeps every PNG."""

from __future__ import annotations

import contextlib
import csv
import io
import re

import cv2
import numpy as np
import pytest

from lasercal.collector.cli.main import main
from lasercal.collector.sessions.spotcam import measure_spot
from lasercal.solver.formats.session import load_session
from lasercal.vision.plane import load_markers

MEASURED = ("camera_x", "camera_y", "camera_sx", "camera_sy", "camera_note")


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(ln for ln in f if not ln.startswith("#")))


def _capture(sheet, folder, capsys, *extra):
    argv = ["capture", "--layout", str(sheet), "--robot", "panda", "--backend", "fake", "--camera", "fake",
            "--auto", "--per-point", "2", "--aim-noise", "3", "--seed", "3", "-o", str(folder)]  # fmt: skip
    assert main(argv + list(extra)) == 0
    return capsys.readouterr().out


@pytest.fixture(scope="module")
def every_png(sheet, tmp_path_factory):
    """The session that keeps every photo as a PNG (the default): its folder and what it printed."""
    folder = tmp_path_factory.mktemp("photos") / "all"
    argv = ["capture", "--layout", str(sheet), "--robot", "panda", "--backend", "fake", "--camera", "fake",
            "--auto", "--per-point", "2", "--aim-noise", "3", "--seed", "3", "-o", str(folder)]  # fmt: skip
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(argv) == 0
    return folder, out.getvalue()


def test_a_session_says_what_its_photos_take(every_png):
    folder, out = every_png  # the session _capture runs, with every photo kept
    each, n, total = re.search(
        r"photos: ([\d.]+) MB each \(PNG\): about ([\d.]+) MB for (\d+) photos", out
    ).groups()
    files = sorted((folder / "photos").iterdir())
    assert int(total) == len(files) == 10
    real = sum(f.stat().st_size for f in files) / 1e6
    assert abs(float(n) - real) < 0.1 * real  # the estimate from the first photo, within 10 %
    wrote = re.search(r"wrote ([\d.]+) MB in .*: 10 photos ([\d.]+) MB", out)
    assert wrote and abs(float(wrote.group(2)) - real) < 0.05 + 1e-9
    assert "--photos first or --photos none or --photo-format jpg keep less" in out


def test_fewer_or_smaller_photos_lose_no_measurement(every_png, sheet, tmp_path, capsys):
    kept_all, _ = every_png
    ref = _rows(kept_all / "captures.csv")
    for keep, fmt in (("none", "png"), ("first", "jpg")):
        folder = tmp_path / f"{keep}-{fmt}"
        # --photos none keeps no photo in any format: --photo-format with it is refused (issue 53)
        fmt_args = ("--photo-format", fmt) if keep != "none" else ()
        out = _capture(sheet, folder, capsys, "--photos", keep, *fmt_args)
        rows = _rows(folder / "captures.csv")
        for r, r0 in zip(rows, ref, strict=True):  # the same captures, measured the same, to the bit
            assert {k: v for k, v in r.items() if k != "photo"} == {
                k: v for k, v in r0.items() if k != "photo"
            }
        kept = [r["photo"] for r in rows if r["photo"]]
        on_disk = (
            sorted(p.relative_to(folder).as_posix() for p in (folder / "photos").glob("*")) if kept else []
        )
        assert sorted(kept) == on_disk  # a row names a photo exactly when it is on disk
        if keep == "none":
            assert not kept and "photos: none kept" in out and not (folder / "photos").exists()
            continue
        # first: the first capture at each point, and every one whose spot the camera could not measure
        seen, want = set(), []
        for r in rows:
            want.append(r["point"] not in seen or r["camera_x"] == "")
            seen.add(r["point"])
        assert [bool(r["photo"]) for r in rows] == want
        assert all(p.endswith(".jpg") for p in kept)
        # a JPEG is a tenth of a PNG, and re-measured (as lasercal spots would: without the lens's
        # calibration, the same for both) its spot is the PNG's within 0.07 mm: 3 x the RMS shift that
        # benchmarks/bench_photos.py measured on another seed's photos (0.023 mm)
        png = {r["photo"]: kept_all / r0["photo"] for r, r0 in zip(rows, ref) if r["photo"]}
        markers = load_markers(sheet)
        for r in rows:
            if r["photo"] and r["camera_x"]:
                jpg, lossless = folder / r["photo"], png[r["photo"]]
                assert jpg.stat().st_size < 0.2 * lossless.stat().st_size
                a, b = (measure_spot(cv2.imread(str(f)), f.name, markers).xy for f in (jpg, lossless))
                assert np.all(np.abs(a - b) < 0.07), (a, b)
        # the session still loads, and resumes with its own photo settings
        assert load_session(folder).measured.sum() == sum(bool(r["camera_x"]) for r in rows)
    assert (
        main(["capture", "--resume", str(tmp_path / "none-png"), "--auto"]) == 0
    )  # complete: nothing to add
    assert "photos kept: none" in capsys.readouterr().out


def test_a_validation_keeps_its_first_photo_as_jpeg_and_measures_every_one(tmp_path, capsys):
    argv = ["validate", "panda_thesis_identified", "--backend", "fake", "--layout", "thesis", "-n", "5"]
    assert main(argv + ["-o", str(tmp_path / "all")]) == 0
    assert main(argv + ["-o", str(tmp_path / "v"), "--photos", "first", "--photo-format", "jpg"]) == 0
    out = capsys.readouterr().out
    rows, ref = _rows(tmp_path / "v" / "validation.csv"), _rows(tmp_path / "all" / "validation.csv")
    assert [r["photo"] for r in rows] == ["photos/0000.jpg", "", "", "", ""]
    assert [r["x_mm"] for r in rows] == [r["x_mm"] for r in ref] and all(r["x_mm"] for r in rows)
    assert [p.name for p in (tmp_path / "v" / "photos").iterdir()] == ["0000.jpg"]
    assert "(JPG): about" in out and re.search(r"wrote [\d.]+ [kM]B in .*v: 1 photo ", out)
