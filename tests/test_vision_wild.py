"""Issue 47 item 17: what an outside check on photos from other cameras met, rendered with known truth
(``vision.render_wild``): a lighter disc or a glint in a spot's halo is that spot's light, not a second
spot; a lamp whose red light an edge cuts is laser-coloured on one side only; a large reddish surface
that does not clip is no laser spot, and does not push a faint true spot out of the report."""

from __future__ import annotations

import numpy as np
import pytest

from lasercal.vision.decide import RULE, judge, refusal
from lasercal.vision.detect import measure_candidates
from lasercal.vision.errors import NoSpotError
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.render_wild import SCENES

# Scored on seeds the rule was not tuned on (issue 51: issue 47 tuned RULE on seeds 0-5, and the bounds were
# the counts those seeds gave). The bounds below are quantiles of the counts' distribution over these 6
# seeds, from each kind's per-photo rates measured on seeds 1000-1111
# (benchmarks/bench_vision_wild_seeds.py; the test's seeds among them): a count of 6 photos is
# Binomial(6, rate), and a bound is its 0.1 % (found) or
# 99.9 % (false spots) quantile -- so that another CPU's rounding, flipping a borderline photo, fails it at
# most 1 in 1,000. A rate measured as 0 (or 1) on all N seeds gives the bound 0 (or 6): its true rate is
# below 3/N (95 %), i.e. such a photo turns up in this test's 6 at most ~6 x 3/N of the time.
SEEDS = range(1000, 1006)


def reported(img):
    """What ``lasercal spots --json --expect any`` reports for a phone JPEG (none when it finds none)."""
    try:
        return measure_photo(img, "x", Options(expect=None), subsampled=True).spots
    except NoSpotError:
        return []


@pytest.fixture(scope="module")
def scored():
    """Per scene kind: found (within max(4 px, 2 x 0.5 px) of the truth) and false spots (farther than
    3 x the core radius + 6 px from it), the outside check's rule, over :data:`SEEDS`; and the most false
    spots in one photo."""
    out = {}
    for kind, draw in SCENES.items():
        found = false = most = 0
        for seed in SEEDS:
            sc = draw(seed)
            d = [np.hypot(s.u - sc.truth[0], s.v - sc.truth[1]) for s in reported(sc.img)]
            found += any(x <= 4.0 for x in d)
            n = sum(x > 3 * sc.radius + 6 for x in d)
            false, most = false + n, max(most, n)
        out[kind] = found, false, most
    return out


def test_a_disc_a_glint_or_a_reddish_surface_is_never_a_second_spot(scored):
    # Before issue 47, seeds 0-5 gave 11 false spots: 5 of 6 lamps at an edge and all 6 reddish surfaces.
    # On the untuned seeds 1000-1111: no disc, glint or reddish surface gave a false spot, 0 of 112 each
    # (the bound: 0); a lamp at an edge gave one in 55 of 112 photos (0.49), never two. Its count over
    # 6 photos is Binomial(6, 0.49), whose 99.9 % quantile is 6: no bound on the count can be set
    # from 6 photos (the tuned seeds' "at most 2" was their draw); the bound is per photo, at most 1.
    false = {kind: f for kind, (_, f, _) in scored.items()}
    assert false["disc in halo"] == false["glint beside"] == false["reddish surface"] == 0, false
    assert scored["lamp at an edge"][2] <= 1, scored["lamp at an edge"]


def test_the_true_spot_is_found_beside_each_distractor(scored):
    # On the untuned seeds 1000-1111: found beside a reddish surface 112 of 112 (bound: 6), beside a
    # lamp at an edge 107 of 112 (Binomial(6, 0.955)'s 0.1 % quantile: 3), beside a disc in the halo
    # 61, beside a glint 17 -- rates whose 0.1 % quantiles over 6 photos are 0: no bound (the tuned
    # seeds 0-5 gave 4 and 1 of 6). A disc that touches the spot's core (13-26 px from its centre) merges
    # with it and pulls the centre a few px; a clipped glint's white light pulls the spot's luma towards it,
    # and the spot's own halo then looks one-sided: refused, the photo reports no spot (never a false one).
    found = {kind: f for kind, (f, _, _) in scored.items()}
    assert found["reddish surface"] == 6 and found["lamp at an edge"] >= 3, found


def test_a_glint_in_a_spots_halo_is_lit_on_one_side():
    # The glint is split from the spot's blob (two lights in one blob, apart in the luma), and its laser
    # colour is on the spot's side only: refused as one-sided, while the spot's own halo is centred on it.
    sc = SCENES["glint beside"](0)
    spots = measure_candidates(sc.img, "red", None, 2.2, True)["red"][0]
    near = [s for s in spots if np.hypot(s.u - sc.truth[0], s.v - sc.truth[1]) < 2]
    glint = [s for s in spots if np.hypot(s.u - sc.distractor[0], s.v - sc.distractor[1]) < 4]
    assert near and glint
    assert all(s.evidence.side < 0.3 and judge(s.evidence, RULE).rule for s in near)
    assert all(s.evidence.side > RULE.side_max and refusal(s.evidence, RULE) == "side" for s in glint)


def test_a_large_reddish_surface_is_refused_as_large():
    sc = SCENES["reddish surface"](0)
    spots = measure_candidates(sc.img, "red", None, 2.2, True)["red"][0]
    big = [s for s in spots if s.evidence.share > RULE.share_max]
    assert big and all(refusal(s.evidence, RULE) == "large" for s in big)
    assert all(s.evidence.clipped_fraction < 0.02 for s in big)
