"""Leave-one-source-out benchmark of the spot decision rule (issues 30, 47, 55), beside the renderer.

Run from the repository root::

    nice python benchmarks/bench_vision_loso.py --cache /tmp/loso.pkl   # ~40 min on 2 busy cores
    nice python benchmarks/bench_vision_loso.py --rendered 60           # fewer rendered photos

The labelled real photos are read from ``../shared/data/real-photos`` (``labels.json``; see its
``PROVENANCE.md``; never copied into the repository). Each photo is measured once as
``lasercal spots --json --expect any PHOTO`` measures it (its candidates through the physical gates,
``vision.detect.measure_candidates``), then each rule decides as the command decides
(``vision.detect.select``; ``vision.fit``): the same spots the command reports under that rule. The
rule's thresholds, every one of :data:`vision.fit.GRIDS` (issue 47's and issue 55's together), and its
probability's calibration are fitted on every source but one, together with rendered photos sampled
wide (``vision.fit.rendered``), photos of coloured paper lit by a laser or by warm light
(``vision.fit.lit_papers``), scenes of what an outside check on other cameras met (``vision.fit.wild``:
a disc or a glint in a spot's halo, a lamp at an edge, a reddish surface) and issue 55's development
renders (``vision.fit.wild55``, seeds 0 to ``--dev`` - 1 of each kind and of the counter-case), and
scored on the source left out: found / labelled (within max(4 px, 2 x the label's uncertainty)),
false spots (farther than 3 x radius + 6 px from every labelled and uncertain spot), crashes (photos
lost to an internal fault, "could not be measured") and the median distance of the found spots. Then
the rule fitted on all sources in-sample, with issue 55's fresh renders (seeds from ``--first``, never
fitted on) scored under it, and the rule in ``vision/decide.py`` (:data:`lasercal.vision.decide.RULE`)
as it stands. ``--cache FILE`` keeps the measured photos (read it if it exists; delete it when the
options change): a re-run only fits and scores.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from lasercal.vision import fit
from lasercal.vision.decide import RULE

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_vision_wild_loso as W  # noqa: E402  issue 55's fresh-render rows and the cache

PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-photos"


def row(name: str, s: fit.Score, rule=None) -> None:
    r = (
        ""
        if rule is None
        else (
            f"  shift {rule.shift_min:.2f} core {rule.core_shift_min:.2f} dominance {rule.dominance:.2f} "
            f"side {rule.side_max:.2f} share {rule.share_max:.2g} bare {rule.bare_shift:.2f} "
            f"neutral {rule.bare_neutral:.2g} adds {rule.adds_share:.2f} lopsided {rule.lopsided_max:.2f} "
            f"lean {rule.lean_min:.2f} "
            f"p = 1/(1+exp(-({rule.offset:.2f} + {rule.slope:.2f} margin + {rule.clipped:.2f} clipped)))"
        )
    )
    print(
        f"{name:<34} {s.photos:>6} {s.found:>5}/{s.labelled:<4} {s.false:>6} {s.unmeasurable:>6} "
        f"{s.median:>9.2f}{r}",
        flush=True,
    )


def header(title: str) -> None:
    print(f"\n## {title}")
    print(f"{'source':<34} {'photos':>6} {'found':>10} {'false':>6} {'crash':>6} {'median px':>9}")


def pooled_rows(real, synth, rule) -> None:
    """The rows of one rule scored on all real photos, the renderer and the lit papers."""
    row("all real", fit.score(real, rule))
    row("renderer", fit.score([p for p in synth if p.source == "renderer"], rule))
    row(
        "lit paper (laser, warm lamps, warm glare)",
        fit.score([p for p in synth if p.source == "lit paper"], rule),
    )
    for kind in ("disc in halo", "glint beside", "lamp at an edge", "reddish surface"):
        row(f"wild: {kind}", fit.score([p for p in synth if p.name.startswith(kind)], rule))
    kinds = ("colourless core", "leaning core", "red object", "red-lit edge", "two white cores")
    for kind in (*kinds, "colourless off balance"):
        row(f"wild: {kind}", fit.score([p for p in synth if p.name.startswith(kind)], rule))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=Path, default=PHOTOS, help="folder with labels.json")
    ap.add_argument("--rendered", type=int, default=120, help="rendered photos in every training set")
    ap.add_argument("--wild", type=int, default=8, help="photos of each wild scene in every training set")
    ap.add_argument("--dev", type=int, default=16, help="issue 55's seeds of each kind in every training set")
    ap.add_argument("--fresh", type=int, default=40, help="issue 55's fresh seeds of each kind, scored only")
    ap.add_argument("--first", type=int, default=200, help="the first fresh seed")
    ap.add_argument("--cache", type=Path, help="keep the measured photos in this file (read it if it exists)")
    a = ap.parse_args()
    t = time.perf_counter()
    real, synth, fresh = W.cached(
        a.cache,
        lambda: (
            fit.measure_labelled(a.photos),
            fit.rendered(a.rendered) + fit.lit_papers(60) + fit.wild(a.wild) + fit.wild55(a.dev),
            fit.wild55(a.fresh, first=a.first),
        ),
    )
    took = time.perf_counter() - t
    print(
        f"measured {len(real)} real, {len(synth)} rendered, {len(fresh)} fresh photos: {took:.0f} s",
        flush=True,
    )

    header("Leave one source out: fitted without the source, scored on it")
    total = fit.Score()
    for src, (rule, s) in fit.leave_one_source_out(real, synth).items():
        row(src, s, rule)
        total = total + s
    row("all (held out)", total)

    header("In-sample: the rule fitted on all sources and the renderer")
    everything = fit.fit_rule(real + synth)
    for src in sorted({p.source for p in real}):
        row(src, fit.score([p for p in real if p.source == src], everything))
    pooled_rows(real, synth, everything)
    print(f"fitted: {everything}")
    W.header("Fresh renders of issue 55's kinds under the rule fitted on all sources")
    W.kind_rows(fresh, everything)

    header("The rule in vision/decide.py (RULE)")
    pooled_rows(real, synth, RULE)
    print(f"RULE: {RULE}")
    W.header("Fresh renders of issue 55's kinds under RULE")
    W.kind_rows(fresh, RULE)
    print(f"\n(benchmark took {time.perf_counter() - t:.0f} s)")


if __name__ == "__main__":
    main()
