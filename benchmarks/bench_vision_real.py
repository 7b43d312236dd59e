"""Benchmark of laser spots in real photographs (issue 22): found / false / distance per camera.

Run from the repository root::

    python benchmarks/bench_vision_real.py                    # ~20 s on 2 cores
    python benchmarks/bench_vision_real.py --photos DIR       # another labelled folder

The photos and their hand labels are in ``../shared/data/real-photos`` (``labels.json``;
``PROVENANCE.md`` gives the sources, licences and the labelling method). They are read from there,
never copied into the repository. Coordinates are in the stored pixel grid (EXIF orientation
ignored), pixel centres at integer coordinates (OpenCV's convention).

Each photo is measured as ``lasercal spots PHOTO`` does (``measure_file`` with the defaults: one spot
expected, laser colour decided from the photo). A labelled spot is found when a spot lies within
max(4 px, 2 x its uncertainty); every other spot is false; "crashes" counts photos lost to an
internal fault ("could not be measured"). Per source folder (one camera each, see PROVENANCE.md):
found / labelled, false spots, crashes, the median and largest distance of the found spots, and the
median time per photo (decoding included). Then red spots pasted onto crops of those photos (their
backgrounds: paper, board, wall, foam, wood), and two synthetic extremes: a 50-megapixel photo and
a 1 x 10,000 px strip.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from lasercal.vision.errors import VisionError
from lasercal.vision.measure import Options, measure_file, measure_photo

PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-photos"


def score(entry: dict, res) -> tuple[int, int, list[float], bool]:
    """Found labels, false spots, distances of the found ones (px) and whether the photo crashed."""
    used, dist = set(), []
    for lab in entry["spots"]:
        d = [np.hypot(s.u - lab["x"], s.v - lab["y"]) for s in res.spots]
        j = int(np.argmin(d)) if d else -1
        if j >= 0 and j not in used and d[j] <= max(4.0, 2.0 * lab["uncertainty_px"]):
            used.add(j)
            dist.append(float(d[j]))
    crashed = res.error is not None and "could not be measured" in res.error
    return len(dist), len(res.spots) - len(used), dist, crashed


def section_real(folder: Path) -> None:
    labels = json.loads((folder / "labels.json").read_text())
    print(f"\n## Real photos in {folder} ({len(labels)} photos), as `lasercal spots` measures them")
    rows = defaultdict(lambda: dict(n=0, labelled=0, found=0, false=0, crashes=0, dist=[], t=[]))
    for entry in labels:
        t = time.perf_counter()
        res = measure_file(folder / entry["file"], Options())
        dt = time.perf_counter() - t
        found, false, dist, crashed = score(entry, res)
        r = rows[entry["file"].split("/")[0]]
        r["n"] += 1
        r["labelled"] += len(entry["spots"])
        r["found"] += found
        r["false"] += false
        r["crashes"] += crashed
        r["dist"] += dist
        r["t"].append(dt)
        why = f"  {res.error[:150]}" if res.error and entry["spots"] else ""
        ev = res.spots[0].evidence if res.spots else None
        rule = f"rule {ev.rule}, rim shift {ev.rim_shift:.1f}" if ev is not None and ev.rim_shift else ""
        print(
            f"  {entry['file']:<58} labelled {len(entry['spots'])} found {found} false {false}"
            f"{' CRASH' if crashed else ''} {' '.join(f'{d:.2f} px' for d in dist)} {rule}{why}"
        )
    print(
        f"\n{'camera (source folder)':<34} {'photos':>6} {'found':>9} {'false':>6} {'crashes':>8} "
        f"{'median px':>10} {'max px':>7} {'s/photo':>8}"
    )
    tot = dict(n=0, labelled=0, found=0, false=0, crashes=0, dist=[], t=[])
    for name, r in sorted(rows.items()):
        for k in tot:
            tot[k] += r[k]
        _row(name, r)
    _row("all", tot)


def _row(name: str, r: dict) -> None:
    d = np.array(r["dist"])
    print(
        f"{name:<34} {r['n']:>6} {r['found']:>4}/{r['labelled']:<4} {r['false']:>6} {r['crashes']:>8} "
        f"{np.median(d) if d.size else float('nan'):>10.2f} {d.max(initial=0):>7.2f} "
        f"{np.median(r['t']):>8.2f}"
    )


# Crops of the real photos free of laser light: (file, (x0, y0, x1, y1)) px, stored grid.
BACKGROUNDS = {
    "brown wall": ("LiamAG+CLS-Beam-Monitor/flashlight.jpg", (200, 200, 1100, 900)),
    "beige paper": ("LiamAG+CLS-Beam-Monitor/laserspotoff.png", (300, 200, 1100, 800)),
    "white board": ("ardab-0+GalvoTracker/laser_im.jpg", (620, 330, 900, 470)),
    "yellow paper": ("LiamAG+CLS-Beam-Monitor/laser1.png", (800, 600, 1280, 960)),
    "wood, clips": ("mampersat+laser-pointer/2011-08-30_00-14-24_821.jpg", (0, 1400, 1200, 2448)),
    "grey foam": ("ardab-0+GalvoTracker/target0.jpg", (760, 150, 1000, 400)),
}


def section_pasted(folder: Path, n: int = 12) -> None:
    """Red laser spots added, in linear light, to crops of the real photos (a Gaussian core of sigma
    2-8 px plus a 2 % exponential scattering halo, 3-100x the paper's red at the peak, leaking
    2-15 % into green and half that into blue), clipped, gamma-encoded and saved as JPEG q90."""
    from lasercal.vision.images import read_image

    print(f"\n## Red spots pasted onto real backgrounds ({n} each): found / false")
    rng = np.random.default_rng(0)
    total = found = false = 0
    for name, (file, (x0, y0, x1, y1)) in BACKGROUNDS.items():
        base = read_image(folder / file)[y0:y1, x0:x1]
        h, w = base.shape[:2]
        yy, xx = np.mgrid[:h, :w]
        marks = ""
        for _ in range(n):
            u, v = rng.uniform(0.3 * w, 0.7 * w), rng.uniform(0.3 * h, 0.7 * h)
            sigma, amp = rng.uniform(2, 8), np.exp(rng.uniform(np.log(3), np.log(100)))
            leak = rng.uniform(0.02, 0.15)
            r = np.hypot(xx - u, yy - v)
            lin = (base / 255.0) ** 2.2
            add = (
                amp
                * lin[..., 2].mean()
                * (np.exp(-(r**2) / (2 * sigma**2)) + 0.02 * np.exp(-r / (3 * sigma)))
            )
            lin += add[..., None] * np.array([0.5 * leak, leak, 1.0])
            img = (255 * np.clip(lin, 0, 1) ** (1 / 2.2)).astype(np.uint8)
            img = cv2.imdecode(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1], cv2.IMREAD_COLOR)
            try:
                spots = measure_photo(img, name, Options(), subsampled=True).spots
            except VisionError:
                spots = []
            hit = any(np.hypot(s.u - u, s.v - v) < max(4.0, sigma) for s in spots)
            total, found, false = total + 1, found + hit, false + len(spots) - hit
            marks += "Y" if hit else ("F" if spots else "-")
        print(f"  {name:<14} {marks}")
    print(f"  found {found}/{total}, false {false}")


def section_extremes() -> None:
    print("\n## Extremes: measured, or one clean line (synthetic paper with one clipped red spot)")
    for shape in ((5773, 8660), (1, 10_000), (16, 10_000)):
        h, w = shape
        img = np.empty((h, w, 3), np.uint8)
        img[:] = (150, 165, 180)
        u, v = 0.37 * w + 0.3, 0.61 * h + 0.7
        yy, xx = np.ogrid[:h, :w]
        if h > 16:  # a spot with a white core and a pink rim; strips are blank paper (refused or no spot)
            y0, y1, x0, x1 = int(v) - 30, int(v) + 30, int(u) - 30, int(u) + 30
            g = np.exp(-((xx[:, x0:x1] - u) ** 2 + (yy[y0:y1] - v) ** 2) / 32.0)
            lin = (img[y0:y1, x0:x1] / 255.0) ** 2.2
            lin[..., 2] += 30 * g
            lin[..., :2] += 1.5 * g[..., None]
            img[y0:y1, x0:x1] = 255 * np.clip(lin, 0, 1) ** (1 / 2.2)
        t = time.perf_counter()
        try:
            res = measure_photo(img, f"{w}x{h}.png", Options())
            what = f"{len(res.spots)} spot, {np.hypot(res.spots[0].u - u, res.spots[0].v - v):.2f} px off"
        except VisionError as exc:
            what = f"one line: {exc}"
        print(f"{w:>6} x {h:<6} {time.perf_counter() - t:6.2f} s  {what[:160]}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--photos", type=Path, default=PHOTOS, help="folder with labels.json (default: %(default)s)"
    )
    args = ap.parse_args()
    t0 = time.time()
    if (args.photos / "labels.json").is_file():
        section_real(args.photos)
        section_pasted(args.photos)
    else:
        print(f"no labels.json in {args.photos}: real photos skipped")
    section_extremes()
    print(f"\n(benchmark took {time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
