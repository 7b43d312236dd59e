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

SEEDS = range(6)


def reported(img):
    """What ``lasercal spots --json --expect any`` reports for a phone JPEG (none when it finds none)."""
    try:
        return measure_photo(img, "x", Options(expect=None), subsampled=True).spots
    except NoSpotError:
        return []


@pytest.fixture(scope="module")
def scored():
    """Per scene kind: found (within max(4 px, 2 x 0.5 px) of the truth) and false spots (farther than
    3 x the core radius + 6 px from it), the outside check's rule, over :data:`SEEDS`."""
    out = {}
    for kind, draw in SCENES.items():
        found = false = 0
        for seed in SEEDS:
            sc = draw(seed)
            d = [np.hypot(s.u - sc.truth[0], s.v - sc.truth[1]) for s in reported(sc.img)]
            found += any(x <= 4.0 for x in d)
            false += sum(x > 3 * sc.radius + 6 for x in d)
        out[kind] = found, false
    return out


def test_a_disc_a_glint_or_a_reddish_surface_is_never_a_second_spot(scored):
    # Before issue 47 these seeds gave 11 false spots: 5 of 6 lamps at an edge and all 6 reddish
    # surfaces (each of which also pushed the faint true spot out of the report). Now none but two
    # lamps whose edge passes so close to the core that its red light lies around it nearly all round
    # (one-sidedness 0.27, under the fitted side_max 0.5: a spot half on a dark mark looks the same).
    false = {kind: f for kind, (_, f) in scored.items()}
    assert false["disc in halo"] == false["glint beside"] == false["reddish surface"] == 0, false
    assert false["lamp at an edge"] <= 2, false


def test_the_true_spot_is_found_beside_each_distractor(scored):
    # Measured on these seeds (before issue 47: 5, 3, 6, 0 of 6; now 4, 1, 6, 6): every spot beside a lamp
    # or a reddish surface. A disc that touches the spot's core (13-26 px from its centre) merges with it
    # and pulls the centre a few px. A clipped glint beside a spot is a loss since issue 47: its white
    # light pulls the brightest part of the spot's luma, the centre of its one-sidedness, towards it, and
    # the spot's own halo then looks one-sided (0.9): refused, the photo reports no spot (never a false one).
    found = {kind: f for kind, (f, _) in scored.items()}
    assert found["lamp at an edge"] == 6 and found["reddish surface"] == 6, found
    assert found["disc in halo"] >= 4 and found["glint beside"] >= 1, found


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
