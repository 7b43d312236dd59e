"""The fake camera's stated spot sigma against its actual error, in the clean world and with every effect on.

``capture --camera fake`` photographs where a robot's beam meets the printed sheet. Here the robot is a
stand-in that reports fixed joint angles (off the fake backend, the fake camera photographs where the
nominal FR3's beam meets the sheet at them: ``StatedTruth``): PER_POINT in-limit FR3 poses aimed beside
each of the sheet's five calibration crosses (``sheet --robot fr3 --place 450 0 0``), each photographed
once and measured as capture measures it (``spotcam.measure_spot``: the stated sigma ``solve`` weights the
capture by). The world is either clean (``none``: the camera as stated, no lens distortion, a round
footprint) or has every effect on (``all``: the lens corrected by camera-calibrate's estimate, an elliptic
footprint, subsurface glow, print scale and shear, sheet height, table slope, paper curl, the arm hiding
spots), its table drawn from WORLD_SEED (``World.draw``).

Each spot is compared with where the beam truly met the paper, in the layout's printed coordinates (the
world's own code): z = error / stated sigma per axis. Prints the z-scores (both axes pooled): RMS,
quantiles, max; the error split into the centroid's (px, against the true hit's pixel) and the plane
map's; and, by resampling SESSION photos (a test's session size) 200,000 times, the quantiles of the
z RMS a test of that size asserts (and of the same statistic with the sigma scaled by 1.5 and 1/1.5).
``--save`` keeps the per-photo numbers (error, sigma) for the tests' bounds.

Run: python benchmarks/bench_camera_sigma.py EFFECTS [PER_POINT] [SEED] [WORLD_SEED] [SESSION] [--save PREFIX]
     (EFFECTS none, all or both, each pose photographed in each world in turn; defaults both 200 7 3 50:
     1,000 poses, ~30 min on an idle core; --save keeps PREFIX-none.npz, PREFIX-all.npz every 5 rounds)
     python benchmarks/bench_camera_sigma.py --report F.npz [SESSION]   (the report of saved photos)
     python benchmarks/bench_camera_sigma.py --bounds F.npz[,G.npz] N [N ...]
     (the tests' bounds from saved photos: for sessions of N photos resampled 200,000 times, the 0.1 % and
     99.9 % quantiles of the z RMS and of the larger axis's mean error, and how often a sigma scaled by 1.5
     or 1 / 1.5 leaves that band; the largest error and |z| from a tail model, ``largest_bound``)
     python benchmarks/bench_camera_sigma.py --tail-check   (that tail model on known distributions)
"""

from __future__ import annotations

import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


class FixedArm:
    """A robot adapter's ``read`` that reports the joint angles set on it."""

    q: np.ndarray

    def read(self):
        return self


def rms(x, axis=None):
    return np.sqrt(np.mean(np.square(x), axis=axis))


def photos(effects: str, per_point: int, seed: int, world_seed: int, save: str | None = None):
    """Measure the photos, each pose in each world of ``effects`` (``none``, ``all`` or ``both``) in turn;
    returns {world: dict of per-photo arrays}, saved to ``save``-WORLD.npz every 5 rounds of the points."""
    from lasercal.collector.cli.main import main as cli
    from lasercal.collector.sessions.spotcam import BESIDE_MM, capture_camera, measure_spot
    from lasercal.collector.worlds import truearm
    from lasercal.collector.worlds.fakeworld import EFFECTS, World, paper_half_length
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.kinematics.aim import aim
    from lasercal.vision.errors import VisionError
    from lasercal.vision.plane import load_markers

    worlds = ("none", "all") if effects == "both" else (effects,)
    work = Path(tempfile.mkdtemp(prefix="bench_sigma_"))
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        cli(["sheet", "-o", str(work), "--robot", "fr3", "--place", "450", "0", "0"])
        layout_file = work / "layout.yaml"
        layout, fr3, arm = load_layout(layout_file), load_model("fr3"), FixedArm()
        cfg = {"backend": "franky", "robot": "fr3", "seed": 0}
        cams = {
            e: capture_camera(
                "fake",
                cfg,
                arm,
                layout,
                layout_file,
                World.draw(EFFECTS if e == "all" else (), world_seed, paper_half_length(layout)),
            )[0]
            for e in worlds
        }
    markers, rng = load_markers(layout_file), np.random.default_rng(seed)
    poses = {
        name: aim(
            fr3,
            layout.sheet.to_base(layout.points[name][None, :2] + BESIDE_MM, layout.plane_z)[0],
            per_point,
            rng,
        )
        for name in layout.calibration
    }
    out = {e: {k: [] for k in ("name", "err", "sig", "px_err", "lost")} for e in worlds}
    for i in range(per_point):
        for name in layout.calibration:
            arm.q = q = poses[name][i]
            for e, cam in cams.items():
                img = cam.photo()
                uv, _, _ = cam.paper.hit(*truearm.beam(fr3, q))
                try:
                    m = measure_spot(img, name, markers, cam.lens)
                except VisionError:
                    out[e]["lost"].append(name)  # hidden by the arm
                    continue
                out[e]["name"].append(name)
                out[e]["err"].append(m.xy - uv[0])
                out[e]["sig"].append(m.sigma)
                out[e]["px_err"].append(np.asarray(_last_px[0]) - cam.view.project(uv)[0])
        if save and ((i + 1) % 5 == 0 or i + 1 == per_point):
            for e in worlds:
                np.savez(f"{save}-{e}.npz", **{k: np.array(v) for k, v in out[e].items()})
    return {e: {k: np.array(v) for k, v in o.items()} for e, o in out.items()}


_last_px = [None]


def _hook():
    """Record the spot's pixel (the detector's) of the last photo measured."""
    from lasercal.vision import measure

    orig = measure.detect_spots

    def detect_spots(*a, **kw):
        spots, warnings = orig(*a, **kw)
        _last_px[0] = (spots[0].u, spots[0].v) if spots else (np.nan, np.nan)
        return spots, warnings

    measure.detect_spots = detect_spots


def report(res: dict, session: int, label: str) -> None:
    err, sig = res["err"], res["sig"]
    z = err / sig
    a = np.abs(z).ravel()
    print(f"{label}: {len(z)} photos measured, {len(res['lost'])} lost (hidden)")
    print(
        f"  z-scores (both axes, k {a.size}): RMS {rms(a):.3f} (x {rms(z[:, 0]):.3f}, y {rms(z[:, 1]):.3f}); "
        f"99 % {np.quantile(a, 0.99):.2f}, 99.9 % {np.quantile(a, 0.999):.2f}, max {a.max():.2f}"
    )
    print(
        f"  error RMS {rms(err):.4f} mm (mean x {err[:, 0].mean():+.4f}, y {err[:, 1].mean():+.4f}), "
        f"stated sigma RMS {rms(sig):.4f} mm; centroid error RMS {rms(res['px_err']):.4f} px"
    )
    for name in dict.fromkeys(res["name"]):
        k = res["name"] == name
        print(
            f"    {name}: z RMS {rms(z[k]):.2f}, error RMS {rms(err[k]):.4f} mm, "
            f"mean {err[k].mean(0).round(4)}"
        )
    idx = np.random.default_rng(0).integers(0, len(z), (200_000, session))
    for f in (1.0, 1.5, 1 / 1.5):
        zr = rms(z[idx] / f, (1, 2))
        print(
            f"  {session} photos resampled 200,000 times, sigma x {f:.3f}: z RMS quantiles 0.1 % "
            f"{np.quantile(zr, 1e-3):.3f}, 99.9 % {np.quantile(zr, 1 - 1e-3):.3f}"
        )


def largest_bound(a: np.ndarray, n: int, risk: float = 1e-3, tail: float = 0.1, boots: int = 300):
    """The largest of a session's ``n`` photos' |values| (both axes) exceeded with probability ``risk``.

    Resampling cannot answer this: a resampled session never exceeds the pool's largest value, while a
    fresh one does in about 2n of every len(a)+1 sessions (4 % at 40 photos of 1,000). So the pool's upper
    ``tail`` is modelled instead: peaks over threshold with a generalised Pareto distribution
    (Pickands-Balkema-de Haan; ``scipy.stats.genpareto``), read at the per-value exceedance
    1 - (1 - risk)^(1 / 2n).

    Parameters
    ----------
    a : (m, 2) array
        |error| (mm) or |z| per photo and axis.
    n : int
        Photos per session.

    Returns
    -------
    (float, float)
        The model's bound, and its bootstrap 95 % upper limit (``boots`` resamples of the photos, the
        threshold and fit redone on each): the bound a test asserts. On pools drawn from a normal and
        t distributions (``--tail-check``) a fresh 40-photo session passes it in 0.12-0.33 % of sessions
        on average; the pool's largest, in 3.5-5.2 %.
    """
    from scipy import stats

    p = 1 - (1 - risk) ** (1 / (2 * n))

    def bound(v):
        u = np.quantile(v, 1 - tail)
        shape, _, scale = stats.genpareto.fit(v[v > u] - u, floc=0)
        return u + stats.genpareto.ppf(1 - p / tail, shape, 0, scale)

    rng = np.random.default_rng(0)
    again = [bound(a[rng.integers(0, len(a), len(a))].ravel()) for _ in range(boots)]
    return float(bound(a.ravel())), float(np.quantile(again, 0.95))


def tail_check(pools: int = 40, n: int = 40) -> None:
    """How often a fresh ``n``-photo session passes ``largest_bound``, for pools of 1,000 photos drawn from
    known distributions (the fraction exact, from each distribution's tail), against the pool's largest."""
    from scipy import stats

    rng = np.random.default_rng(1)
    for name, dist in (("normal", stats.norm()), ("t, 8 dof", stats.t(8)), ("t, 4 dof", stats.t(4))):
        passed = np.array(
            [
                [1 - (1 - 2 * dist.sf(b)) ** (2 * n) for b in (*largest_bound(a, n, boots=100), a.max())]
                for a in np.abs(dist.rvs((pools, 1000, 2), random_state=rng))
            ]
        )
        print(
            f"  {name}: fresh {n}-photo sessions passing the bound, mean over {pools} pools: tail model "
            f"{passed[:, 0].mean():.2%}, its 95 % upper limit {passed[:, 1].mean():.2%}, the pool's largest "
            f"{passed[:, 2].mean():.2%}"
        )


def bounds(path: str, sizes, draws: int = 200_000) -> None:
    """The bounds a test of ``sizes`` photos asserts, from the photos saved in ``path`` (see above)."""
    res = [np.load(p) for p in path.split(",")]  # several runs' photos pooled
    err = np.concatenate([r["err"] for r in res])
    z = err / np.concatenate([r["sig"] for r in res])
    print(f"{path}: {len(z)} photos, z RMS {rms(z):.3f}")
    for n in sizes:
        idx = np.random.default_rng(n).integers(0, len(z), (draws, n))
        zr = rms(z[idx], (1, 2))
        lo, hi = np.quantile(zr, [1e-3, 1 - 1e-3])
        worst = largest_bound(np.abs(err), n)
        mean = np.quantile(np.abs(err[idx].mean(1)).max(1), [1 - 1e-3, 1 - 1e-4])  # the larger axis's
        zmax = largest_bound(np.abs(z), n)
        out = [np.mean((zr / f < lo) | (zr / f > hi)) for f in (1.5, 1 / 1.5)]
        print(
            f"  {n} photos, {draws:,} draws: z RMS 0.1 % {lo:.3f}, 99.9 % {hi:.3f}; "
            f"largest |z| 99.9 % {zmax[0]:.2f} (95 % upper {zmax[1]:.2f}); "
            f"largest error 99.9 % {worst[0]:.4f} (95 % upper {worst[1]:.4f}) mm; "
            f"mean error (larger axis) 99.9 % {mean[0]:.4f}, "
            f"99.99 % {mean[1]:.4f} mm; sessions outside the band with the sigma x 1.5: "
            f"{out[0]:.4f}, x 1/1.5: {out[1]:.4f}"
        )


def main(argv) -> None:
    if argv and argv[0] == "--bounds":
        bounds(argv[1], [int(a) for a in argv[2:]])
        return
    if argv and argv[0] == "--tail-check":
        tail_check()
        return
    if argv and argv[0] == "--report":
        report(dict(np.load(argv[1])), int(argv[2]) if len(argv) > 2 else 50, argv[1])
        return
    save = None
    if "--save" in argv:
        i = argv.index("--save")
        save, argv = argv[i + 1], argv[:i] + argv[i + 2 :]
    effects = argv[0] if argv else "both"
    per_point, seed, world_seed, session = (
        int(a) for a in (argv[1:] + ["200", "7", "3", "50"][len(argv) - 1 :])[:4]
    )
    _hook()
    t = time.time()
    for e, res in photos(effects, per_point, seed, world_seed, save).items():
        report(res, session, f"effects {e}, world seed {world_seed}, pose seed {seed}, {per_point} per point")
    print(f"  {time.time() - t:.0f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
