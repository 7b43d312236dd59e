"""What a session's photos take on disk, PNG against JPEG, and what JPEG costs a re-measurement.

A fake camera capture session (sheet at 450 0 0, every world effect, 2 captures per point: 10 photos of
1280 x 960) and a fake validation (thesis layout, 10 photos of 800 x 600) keep every photo as PNG; each
photo is then encoded as JPEG (quality 95, as ``--photo-format jpg`` writes it) and both are measured again
as ``lasercal spots`` would (the capture's through the sheet's markers, without the lens's calibration,
the same for both): the table gives the sizes and how far the JPEG's spot lies from the PNG's, against
the sigma the session recorded. The session's own measurement is made on the photo in memory before it is
stored, so it does not depend on the format (tests/test_photos.py checks it to the bit).

Run: ``nice python benchmarks/bench_photos.py`` (about a minute).
"""

from __future__ import annotations

import csv
import io
import tempfile
from contextlib import redirect_stdout
from pathlib import Path

import cv2
import numpy as np

from lasercal.collector.cli.main import main
from lasercal.collector.sessions.photos import JPEG_QUALITY
from lasercal.collector.sessions.spotcam import measure_spot
from lasercal.vision.detect import detect_spots
from lasercal.vision.plane import load_markers
from lasercal.vision.sheet import design_sheet, write_layout


def rows(path: Path) -> list[dict]:
    with open(path) as f:
        return list(csv.DictReader(ln for ln in f if not ln.startswith("#")))


def jpeg(img: np.ndarray) -> bytes:
    return cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])[1].tobytes()


def main_bench() -> None:
    work = Path(tempfile.mkdtemp(prefix="bench_photos_"))
    sheet = work / "layout.yaml"
    write_layout(sheet, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 0.0, "yaw_deg": 0.0})
    with redirect_stdout(io.StringIO()):
        main(["capture", "--layout", str(sheet), "--robot", "panda", "--backend", "fake", "--camera", "fake",
              "--auto", "--per-point", "2", "--aim-noise", "3", "-o", str(work / "s")])  # fmt: skip
        main(["validate", "panda_thesis_identified", "--backend", "fake", "--layout", "thesis", "-n", "10",
              "-o", str(work / "v")])  # fmt: skip
    markers = load_markers(sheet)
    png, jpg, shift, sigma = [], [], [], []
    for r in rows(work / "s" / "captures.csv"):
        f = work / "s" / r["photo"]
        img = cv2.imread(str(f))
        png.append(f.stat().st_size)
        data = jpeg(img)
        jpg.append(len(data))
        if r["camera_x"]:
            a = measure_spot(img, "png", markers).xy
            b = measure_spot(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR), "jpg", markers).xy
            shift.append(np.abs(b - a))
            sigma.append([float(r["camera_sx"]), float(r["camera_sy"])])
    shift, sigma = np.array(shift), np.array(sigma)
    print("capture photos (1280 x 960, fake sheet camera):")
    print(f"  PNG  {np.mean(png) / 1e6:.2f} MB each; 45 captures: {45 * np.mean(png) / 1e6:.0f} MB")
    each = np.mean(jpg) / 1e6
    print(f"  JPEG {each:.3f} MB each (q{JPEG_QUALITY}); 45 captures: {45 * each:.1f} MB")
    print(
        f"  JPEG re-measured vs PNG: max {shift.max():.3f} mm, RMS {np.sqrt(np.mean(shift**2)):.3f} mm; "
        f"max {np.max(shift / sigma):.2f} x the recorded sigma ({len(shift)} spots)"
    )
    png, jpg, shift = [], [], []
    for r in rows(work / "v" / "validation.csv"):
        f = work / "v" / r["photo"]
        img = cv2.imread(str(f))
        png.append(f.stat().st_size)
        data = jpeg(img)
        jpg.append(len(data))
        a = detect_spots(img, "png")[0][0]
        b = detect_spots(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR), "jpg")[0][0]
        shift.append(np.hypot(a.u - b.u, a.v - b.v))
    print("validation photos (800 x 600, fake top view at 0.2 mm/px):")
    print(f"  PNG  {np.mean(png) / 1e6:.2f} MB each; 60 photos: {60 * np.mean(png) / 1e6:.0f} MB")
    print(f"  JPEG {np.mean(jpg) / 1e6:.3f} MB each; 60 photos: {60 * np.mean(jpg) / 1e6:.1f} MB")
    print(f"  JPEG re-measured vs PNG: max {max(shift):.3f} px = {0.2 * max(shift):.3f} mm")
    print(f"(work folder {work})")


if __name__ == "__main__":
    main_bench()
