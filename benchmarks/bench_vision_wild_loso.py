"""Issue 55's thresholds fitted and scored leave one source out, on the shared photos and on fresh renders.

Run from the repository root::

    nice python benchmarks/bench_vision_wild_loso.py                  # ~15 min on 2 busy cores
    nice python benchmarks/bench_vision_wild_loso.py --fresh 20 --cache /tmp/w55.pkl

Issue 55's thresholds (``vision.fit.ISSUE_55``: ``bare_shift``, ``adds_share``, ``lopsided_max``,
``lean_min``) are chosen by ``vision.fit.fit_rule`` with the other thresholds and the probability held as
``vision.decide.RULE`` has them (fitted leave one source out by ``bench_vision_loso.py``, issue 47). Every
photo is measured once as ``lasercal spots --json --expect any PHOTO`` measures it, then each rule decides
as the command decides (``vision.fit``). The training set of every fit holds the development renders:
issue 55's four kinds and the two-white-cores counter-case, seeds 0-15 of each (``fit.wild55``), 40
ordinary phone renders (``fit.rendered``), 30 lit papers and 4 of each issue-47 wild scene.

1. The shared photos (``../shared/data/real-photos``), leave one source out: for each source, the
   thresholds fitted on every other source and the renders, scored on it.
2. Fresh renders of the four kinds (seeds from ``--first``, 200 by default, never used to choose
   anything), scored under the thresholds fitted on all shared photos and the development renders.
3. The same fresh renders and the shared photos under ``RULE`` as it stands in ``vision/decide.py``.

Found: a reported spot within max(4 px, 2 x the label's uncertainty); false: a reported spot farther
than 3 x radius + 6 px from every labelled and uncertain spot (the outside check's scoring).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import asdict
from pathlib import Path

from lasercal.vision import fit
from lasercal.vision.decide import RULE

PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-photos"
KINDS = ("colourless core", "leaning core", "red object", "red-lit edge")


def row(name: str, s: fit.Score, rule=None) -> None:
    r = "" if rule is None else "  " + " ".join(f"{k} {asdict(rule)[k]:.3g}" for k in fit.ISSUE_55)
    print(
        f"{name:<34} {s.photos:>6} {s.found:>5}/{s.labelled:<4} {s.false:>6} {s.median:>9.2f}{r}", flush=True
    )


def header(title: str) -> None:
    print(f"\n## {title}")
    print(f"{'source':<34} {'photos':>6} {'found':>10} {'false':>6} {'median px':>9}")


def kind_rows(fresh: list, rule) -> None:
    """Each fresh kind's row, the four kinds together, and the counter-case."""
    total = fit.Score()
    for kind in KINDS:
        s = fit.score([p for p in fresh if p.name.startswith(kind)], rule)
        row(f"fresh: {kind}", s)
        total = total + s
    row("fresh: all four kinds", total)
    row(
        "fresh: two white cores (refuse)",
        fit.score([p for p in fresh if p.name.startswith("two white")], rule),
    )
    row(
        "fresh: colourless, balance off",
        fit.score([p for p in fresh if p.name.startswith("colourless off")], rule),
    )


def cached(path: Path | None, build):
    """``build()``, kept in ``path`` (or read from it if it exists): the measured spots hold their deferred
    precise fits, closures, which cloudpickle keeps and pickle cannot. The file is not checked against the
    options: delete it when they change."""
    if path is None:
        return build()
    import cloudpickle as pickle

    if path.exists():
        return pickle.loads(path.read_bytes())
    out = build()
    path.write_bytes(pickle.dumps(out))
    return out


def measured(a) -> tuple[list, list, list]:
    """The shared, development and fresh photos, measured (or read from ``--cache``)."""
    return cached(
        a.cache,
        lambda: (
            fit.measure_labelled(a.photos),
            fit.wild55(a.dev) + fit.rendered(40) + fit.lit_papers(30) + fit.wild(4),
            fit.wild55(a.fresh, first=a.first),
        ),
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=Path, default=PHOTOS, help="folder with labels.json")
    ap.add_argument("--dev", type=int, default=16, help="development seeds of each issue-55 kind (0 on)")
    ap.add_argument("--fresh", type=int, default=40, help="fresh seeds of each kind, scored only")
    ap.add_argument("--first", type=int, default=200, help="the first fresh seed")
    ap.add_argument("--cache", type=Path, help="keep the measured photos in this file (read it if it exists)")
    a = ap.parse_args()
    t = time.perf_counter()
    real, dev, fresh = measured(a)
    took = time.perf_counter() - t
    print(f"measured {len(real)} shared, {len(dev)} development, {len(fresh)} fresh photos: {took:.0f} s")

    header("Shared photos, leave one source out: issue 55's thresholds fitted without the source")
    total = fit.Score()
    for src, (rule, s) in fit.leave_one_source_out(real, dev, fields=fit.ISSUE_55).items():
        row(src, s, rule)
        total = total + s
    row("all (held out)", total)

    header("Fresh renders: issue 55's thresholds fitted on all shared photos and the development renders")
    everything = fit.fit_rule(real + dev, fields=fit.ISSUE_55)
    row("fitted", fit.score(real, everything), everything)
    kind_rows(fresh, everything)

    header("RULE as it stands in vision/decide.py")
    row("all shared (in-sample)", fit.score(real, RULE), RULE)
    kind_rows(fresh, RULE)
    print(f"\n(benchmark took {time.perf_counter() - t:.0f} s)")


if __name__ == "__main__":
    main()
