"""Benchmark of the vision package against rendered truth: accuracy (px, mm), detection rate, speed.

Run from the repository root::

    python benchmarks/bench_vision.py            # full: ~10 min on 2 cores
    python benchmarks/bench_vision.py --quick    # ~2 min, fewer samples

Prints the numbers quoted in the README section. All photos come from
``vision.render`` with fixed seeds; pixels in OpenCV's convention, lengths in mm,
times in ms of wall clock after decoding (the photo is already an array).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from lasercal.vision.camera import Camera
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError
from lasercal.vision.imagej import measure as imagej_measure
from lasercal.vision.images import to_gray
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.plane import MarkerLayout, find_fiducials
from lasercal.vision.render import (
    Glare,
    LaserSpot,
    Photo,
    cross_print,
    ink_dot,
    look_down,
    marker_prints,
    marker_sheet,
    render,
)

IMAGEJ = [(t, m) for t in ("default", "otsu") for m in ("centroid", "com")]
CLEAN = dict(paper=0.5)
HARSH = dict(paper=0.5, jpeg=90, gamma=2.2, bloom=0.3, gradient=0.2)


def rms(e):
    e = np.asarray(e, float)
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def centroid_trial(rng, n, spot_kw, photo_kw, seed0):
    """Precise and ImageJ (64-px box a person draws, off-centre by up to 8 px) errors, px."""
    view = look_down((200, 200), 0.3)
    res = {"precise": [], "sigma": []} | {f"imagej {t} {m}": [] for t, m in IMAGEJ}
    fails = {k: 0 for k in res}
    for i in range(n):
        kw = {k: (rng.uniform(*v) if isinstance(v, tuple) else v) for k, v in spot_kw.items()}
        u, v = rng.uniform(90, 110, 2)
        img = render(Photo(view, spots=(LaserSpot(u, v, **kw),), **photo_kw), seed0 + i)
        try:
            s = detect_spots(img, luma=photo_kw.get("jpeg") is not None)[0][0]  # as the CLI does for JPEGs
            res["precise"].append(np.hypot(s.u - u, s.v - v))
            res["sigma"].append(np.hypot(s.sigma_u, s.sigma_v))
        except VisionError:
            fails["precise"] += 1
        ox, oy = rng.integers(-8, 9, 2)
        box = (int(u) - 32 + ox, int(v) - 32 + oy, int(u) + 32 + ox, int(v) + 32 + oy)
        for t, m in IMAGEJ:
            try:
                s = imagej_measure(img, box, m, t)
                res[f"imagej {t} {m}"].append(np.hypot(s.u - u, s.v - v))
            except VisionError:
                fails[f"imagej {t} {m}"] += 1
    return res, fails


def section_centroids(rng, n):
    print(
        f"\n## Centroid error, px (RMS of the 2-D error over {n} spots; failures = threshold did not isolate "
        "the spot; gross = error > 1 px)"
    )
    cases = {
        "clean, unsaturated (sigma 1.5-3 px)": (dict(sigma=(1.5, 3.0), peak=(0.25, 0.4)), CLEAN),
        "saturated + speckle 0.3 + JPEG q90": (dict(sigma=(1.5, 3.0), peak=(2.0, 6.0), speckle=0.3), HARSH),
    }
    print(f"{'case':<40} {'method':<26} {'RMS px':>8} {'fail':>5} {'gross':>6}")
    for name, (sk, pk) in cases.items():
        res, fails = centroid_trial(rng, n, sk, pk, 1000)
        for k, e in res.items():
            if k == "sigma":
                continue
            e = np.asarray(e)
            ok = e[e <= 1.0]
            print(f"{name:<40} {k:<26} {rms(ok):8.3f} {fails[k]:5d} {int((e > 1).sum()):6d}")
        print(f"{name:<40} {'precise: reported sigma':<26} {rms(res['sigma']):8.3f}")


def section_speckle(rng, n):
    print(f"\n## Error vs speckle contrast (saturated, JPEG q90, grain 1.5 px; {n} spots each), px RMS")
    print(f"{'contrast':>8} {'precise':>8} {'sigma':>8} {'imagej otsu com':>16}")
    for c in (0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0):
        res, fails = centroid_trial(rng, n, dict(sigma=(1.5, 3.0), peak=(2.0, 6.0), speckle=c), HARSH, 2000)
        print(
            f"{c:8.1f} {rms(res['precise']):8.3f} {rms(res['sigma']):8.3f} "
            f"{rms(res['imagej otsu com']):16.3f}"
        )


def big_photo(rng, seed, n_spots=1, clutter=True, dist=(0, 0, 0, 0, 0)):
    """A 12-MP (4000x3000) photo at 0.3 mm/px: four 50-mm markers, spots, and room-light clutter."""
    view = look_down(
        (4000, 3000),
        0.3,
        centre=(450.0, 0.0),
        tilt_deg=tuple(rng.uniform(-1.5, 1.5, 2)),
        yaw_deg=rng.uniform(-15, 15),
        dist=dist,
        z=-8,
    )
    markers = marker_sheet(view, side=50, inset=0.06)
    prints = marker_prints(markers)
    glares = ()
    if clutter:
        xy = view.unproject(rng.uniform([600, 500], [3400, 2500], (6, 2)))
        prints += tuple(cross_print(p, 12) for p in xy[:4]) + tuple(ink_dot(p, 5) for p in xy[4:])
        glares = (Glare(*rng.uniform([400, 400], [3600, 2600]), rng.uniform(4, 10), rng.uniform(1, 3)),)
    # Spots away from the clutter (printed marks under a spot bias any centroid: see the README).
    uv = rng.uniform([700, 600], [3300, 2400], (n_spots, 2))
    spots = tuple(
        LaserSpot(u, v, rng.uniform(1.5, 3.5), rng.uniform(0.6, 6.0), speckle=rng.uniform(0, 0.4))
        for u, v in uv
    )
    photo = Photo(
        view,
        prints,
        spots,
        glares,
        paper=rng.uniform(0.4, 0.65),
        gradient=rng.uniform(-0.3, 0.3),
        vignetting=rng.uniform(0, 0.25),
        jpeg=int(rng.integers(80, 96)),
        gamma=2.2,
        bloom=0.3,
    )
    return view, markers, photo, render(photo, seed)


def section_plane(rng, n):
    print(f"\n## Spot on the plane, 12-MP photos at 0.3 mm/px with four markers ({n} photos x 5 spots)")
    for label, dist in (
        ("no lens distortion", (0, 0, 0, 0, 0)),
        ("distortion k1=-0.08, camera YAML", (-0.08, 0.02, 0, 0, 0)),
    ):
        errs = {"precise": [], "imagej otsu com": []}
        h_rms = []
        for i in range(n):
            view, markers, photo, img = big_photo(rng, 3000 + i, n_spots=5, clutter=False, dist=dist)
            lay = MarkerLayout("bench", "DICT_4X4_50", markers, 3)
            cam = Camera(view.size, view.K, view.dist) if any(dist) else None
            truth = view.unproject(photo.truth())
            for key, opts in (
                ("precise", Options(expect=None)),
                (
                    "imagej otsu com",
                    Options(method="imagej", imagej_threshold="otsu", imagej_mode="com", expect=None),
                ),
            ):
                res = measure_photo(img, "bench", opts, lay, cam, subsampled=True)
                got = np.array([[s.x_mm, s.y_mm] for s in res.spots])
                errs[key] += [np.min(np.hypot(*(got - p).T)) for p in truth]
                if key == "precise":
                    h_rms.append(res.plane.rms_mm)
        for key, e in errs.items():
            print(f"{label:<36} {key:<16} RMS {rms(e):.3f} mm, max {np.max(e):.3f} mm")
        print(f"{label:<36} homography fit RMS {np.mean(h_rms):.4f} mm (marker corners)")


def section_detection(rng, n):
    print(
        f"\n## Detection without a reference photo, {n} 12-MP photos (crosses, red ink, a glare, JPEG "
        "q80-95, "
        "1 spot each)"
    )
    ok, times, ij_whole, ij_box = 0, [], {k: 0 for k in IMAGEJ}, {k: 0 for k in IMAGEJ}
    for i in range(n):
        view, markers, photo, img = big_photo(rng, 4000 + i)
        u, v = photo.truth()[0]
        t = time.perf_counter()
        try:
            spots, _ = detect_spots(img, luma=True)
            good = len(spots) == 1 and np.hypot(spots[0].u - u, spots[0].v - v) < 1.0
        except VisionError:
            good = False
        times.append(time.perf_counter() - t)
        ok += good
        for t_, m in IMAGEJ:
            box = (int(u) - 32, int(v) - 32, int(u) + 32, int(v) + 32)
            for store, b in ((ij_box, box), (ij_whole, (0, 0, 4000, 3000))):
                try:
                    s = imagej_measure(img, b, m, t_)
                    store[(t_, m)] += np.hypot(s.u - u, s.v - v) > 1.0
                except VisionError:
                    store[(t_, m)] += 1
    print(
        f"precise: {ok}/{n} detected ({100 * ok / n:.1f} %), median {1e3 * np.median(times):.0f} ms, "
        f"max {1e3 * np.max(times):.0f} ms per photo"
    )
    for k in IMAGEJ:
        print(
            f"imagej {k[0]:<8} {k[1]:<8}: failed or > 1 px off: {ij_box[k]}/{n} with a 64-px box, "
            f"{ij_whole[k]}/{n} on the whole photo"
        )


def section_speed(rng, repeats):
    print(f"\n## Speed on one 12-MP photo after decoding (median of {repeats}), ms")
    view, markers, photo, img = big_photo(rng, 5000, n_spots=1)
    lay = MarkerLayout("bench", "DICT_4X4_50", markers, 3)

    def timed(f):
        f()
        ts = []
        for _ in range(repeats):
            t = time.perf_counter()
            f()
            ts.append(time.perf_counter() - t)
        return 1e3 * np.median(ts)

    print(f"spot detection + precise centroid: {timed(lambda: detect_spots(img, luma=True)):.0f}")
    print(
        f"imagej method (detection + emulation): "
        f"{timed(lambda: detect_spots(img, method='imagej', imagej_threshold='otsu')):.0f}"
    )
    print(f"markers (ArUco + edge-fitted corners): {timed(lambda: find_fiducials(to_gray(img), lay)):.0f}")
    print(
        f"whole photo (spots + markers + homography): "
        f"{timed(lambda: measure_photo(img, 'b', Options(), lay, subsampled=True)):.0f}"
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer samples (~2 min)")
    args = ap.parse_args()
    q = args.quick
    t0 = time.time()
    section_centroids(np.random.default_rng(1), 60 if q else 300)
    section_speckle(np.random.default_rng(2), 30 if q else 100)
    section_plane(np.random.default_rng(3), 2 if q else 8)
    section_detection(np.random.default_rng(4), 20 if q else 100)
    section_speed(np.random.default_rng(5), 5 if q else 15)
    print(f"\n(benchmark took {time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
