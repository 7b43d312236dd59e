"""Issue 51: the distribution of tests/test_vision_wild.py's counts over seeds the rule was not tuned on.

    python benchmarks/bench_vision_wild_seeds.py [--first 1000] [--count 100] [--out FILE]

Per scene kind of ``vision.render_wild`` and seed: whether the true spot is found (a reported spot within
4 px of the truth) and how many false spots are reported (farther than 3 x the core radius + 6 px), as the
test scores them; one line per seed to FILE (a rerun appends), then per kind the found rate, the false-spot
rate and the distribution of the test's counts over batches of 6 seeds (binomial from the rate, and the
batches actually drawn).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from lasercal.vision.errors import NoSpotError
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.render_wild import SCENES


def reported(img):
    try:
        return measure_photo(img, "x", Options(expect=None), subsampled=True).spots
    except NoSpotError:
        return []


def score(kind: str, seed: int) -> tuple[int, int]:
    sc = SCENES[kind](seed)
    d = [np.hypot(s.u - sc.truth[0], s.v - sc.truth[1]) for s in reported(sc.img)]
    return int(any(x <= 4.0 for x in d)), int(sum(x > 3 * sc.radius + 6 for x in d))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--out", default="bench_vision_wild.txt")
    a = ap.parse_args()
    out = Path(a.out)
    t = time.time()
    for seed in range(a.first, a.first + a.count):
        line = " ".join(f"{k.replace(' ', '_')}={','.join(map(str, score(k, seed)))}" for k in SCENES)
        with open(out, "a") as f:
            f.write(f"seed {seed} {line}\n")
    print(f"{a.count} seeds in {time.time() - t:.0f} s")
    summarise(out)


def summarise(path: Path) -> None:
    rows = [ln.split() for ln in path.read_text().splitlines() if ln.startswith("seed ")]
    for kind in SCENES:
        key = kind.replace(" ", "_")
        v = np.array([[int(x) for x in tok.split("=")[1].split(",")] for r in rows for tok in r[2:]
                      if tok.startswith(key + "=")])  # fmt: skip
        found, false = v[:, 0], v[:, 1]
        batches = len(v) // 6
        bf = found[: 6 * batches].reshape(batches, 6).sum(1)
        bx = false[: 6 * batches].reshape(batches, 6).sum(1)
        print(
            f"{kind}: {len(v)} seeds: found {found.mean():.3f}, false spots per photo {false.mean():.3f} "
            f"(photos with any {np.mean(false > 0):.3f}, max {false.max()}); per 6 seeds: found "
            f"{np.bincount(bf, minlength=7).tolist()}, false {np.bincount(bx).tolist()} (counts of batches)"
        )


if __name__ == "__main__":
    main()
