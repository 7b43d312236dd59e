"""Benchmark of large clipped laser spots as phones record them (issue 41): found, false, centre error.

Run from the repository root::

    python benchmarks/bench_vision_clipped.py            # ~5-10 min on 2 cores (128 photos a seed)
    python benchmarks/bench_vision_clipped.py --seeds 2  # two draws of every cell
    python benchmarks/bench_vision_clipped.py --profiles # also the ring profiles against the real photos

Every photo comes from ``vision.render_clipped.clipped_scene``: a 640 x 480 crop of a 12-megapixel
phone photo (0.1 mm/px) holding one spot whose laser channel clips out to the core radius (5-30 px
along the beam's minor axis, tilted 0-40 deg), at 2-30x the clipping level, red or green, on white,
grey, yellow or dark paper, with a grey disc ~110 px beyond the spot's plateau and a clipped white
glint ~120 px on the other side; cross-talk, scatter wing, highlight desaturation, chroma noise
reduction and JPEG quality drawn per photo (fixed seeds). Each is measured as
``lasercal spots --json --expect any PHOTO`` measures it. A spot is found within max(4 px, 0.2 x the
core radius) of the truth; a reported spot farther than 3 x the core radius + 6 px from it is false
(the outside check's rule for real photos). "centre px": median and largest distance of the found ones.
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
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.render_clipped import PAPERS, clipped_scene

RADII = (5, 10, 20, 30)
EXPOSURES = (2, 4, 10, 30)
PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-photos"


def score(scene, spots, core_radius: float) -> tuple[bool, int, float]:
    """Found, false spots, distance of the nearest spot (px; inf when none)."""
    d = [float(np.hypot(s.u - scene.truth[0], s.v - scene.truth[1])) for s in spots]
    near = min(d, default=np.inf)
    return near <= max(4.0, 0.2 * core_radius), sum(x > 3 * core_radius + 6 for x in d), near


def sweep(seeds: int) -> None:
    rows = defaultdict(lambda: dict(n=0, found=0, false=0, d=[]))
    t0 = time.perf_counter()
    for seed in range(seeds):
        for colour in ("red", "green"):
            for paper in PAPERS:
                for rc in RADII:
                    for e in EXPOSURES:
                        sc = clipped_scene(seed, colour, rc, e, paper)
                        try:
                            spots = measure_photo(sc.img, "x", Options(expect=None), subsampled=True).spots
                        except VisionError:
                            spots = []
                        found, false, near = score(sc, spots, rc)
                        for key in (f"{colour} {paper}", f"core r {rc:>2} px", f"exposure {e:>2}x", "all"):
                            r = rows[key]
                            r["n"] += 1
                            r["found"] += found
                            r["false"] += false
                            r["d"] += [near] if found else []
    print(f"\n## Large clipped spots ({seeds} seed(s), {time.perf_counter() - t0:.0f} s)")
    print(f"{'cell':<20} {'photos':>6} {'found':>7} {'false':>6} {'median px':>10} {'max px':>7}")
    for key, r in rows.items():
        d = np.array(r["d"]) if r["d"] else np.array([np.nan])
        print(f"{key:<20} {r['n']:>6} {r['found']:>7} {r['false']:>6} {np.median(d):>10.2f} {d.max():>7.2f}")


def profile(img: np.ndarray, u: float, v: float, ch: int) -> dict:
    """A clipped spot's radial profile about (u, v), px: the white core's radius (its component of
    all channels >= 247, as a disc of its area), the ring's width (from the core's edge out to where
    the radial mean of the colour excess, the laser's channel over its neighbour, falls below half
    its peak) and the ring's hue there (OpenCV degrees, 0-180; circular mean)."""
    h, w = img.shape[:2]
    yy, xx = np.mgrid[:h, :w]
    r = np.hypot(xx - u, yy - v)
    white = (img >= 247).all(axis=2)
    n, lab = cv2.connectedComponents(white.astype(np.uint8))
    iu, iv = int(round(u)), int(round(v))
    core = (lab == lab[iv, iu]) if white[iv, iu] else np.zeros_like(white)
    r_core = float(np.sqrt(core.sum() / np.pi))
    nb = img[..., 1] if ch == 2 else np.maximum(img[..., 0], img[..., 2])
    excess = img[..., ch].astype(float) - nb
    bins = np.minimum(r.astype(int), 120)
    ok = ~core & (r < 120)
    radial = np.bincount(bins[ok], excess[ok], 121) / np.maximum(np.bincount(bins[ok], minlength=121), 1)
    start = int(np.ceil(r_core))
    peak = int(start + np.argmax(radial[start:]))
    outer = peak
    while outer < 120 and radial[outer + 1] >= 0.5 * radial[peak]:
        outer += 1
    band = ~core & (r >= r_core) & (r <= outer + 1)
    ang = np.deg2rad(cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[..., 0][band].astype(float) * 2)
    hue = float(np.rad2deg(np.arctan2(np.sin(ang).mean(), np.cos(ang).mean())) / 2 % 180)
    return dict(core=r_core, ring=outer + 1 - r_core, hue=hue)


def profiles() -> None:
    """The real photos' clipped spots against the renderer's, core radius / ring width / ring hue."""
    print("\n## Profiles: real photos with a white core (labels' centres)")
    print(f"{'photo':<50} {'core r px':>9} {'ring px':>8} {'hue deg':>8}")
    labels = json.loads((PHOTOS / "labels.json").read_text()) if (PHOTOS / "labels.json").is_file() else []
    for e in labels:
        for s in e["spots"]:
            if not s.get("cross_check", {}).get("white_core") or "LiamAG" in e["file"]:
                continue
            img = cv2.imread(str(PHOTOS / e["file"]), cv2.IMREAD_COLOR | cv2.IMREAD_IGNORE_ORIENTATION)
            p = profile(img, s["x"], s["y"], 2 if s["colour"] == "red" else 1)
            print(f"{e['file']:<50} {p['core']:>9.1f} {p['ring']:>8.1f} {p['hue']:>8.0f}")
    print("\n## Profiles: the renderer, red on white and dark paper, core radius 12 px, by exposure")
    print(f"{'paper':<8} {'exposure':>8} {'core r px':>9} {'ring px':>8} {'hue deg':>8}")
    for paper in ("white", "dark"):
        for e in EXPOSURES:
            p = np.array([list(profile(sc.img, *sc.truth, 2).values()) for sc in _scenes(paper, e)])
            core, ring, hue = np.nanmedian(p, axis=0)
            print(f"{paper:<8} {e:>8} {core:>9.1f} {ring:>8.1f} {hue:>8.0f}")


def _scenes(paper: str, exposure: float, n: int = 4):
    return [clipped_scene(seed, "red", 12, exposure, paper) for seed in range(n)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=1, help="draws of every cell")
    ap.add_argument("--profiles", action="store_true", help="also the ring profiles against the real photos")
    a = ap.parse_args()
    if a.profiles:
        profiles()
    sweep(a.seeds)


if __name__ == "__main__":
    main()
