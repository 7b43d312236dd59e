"""Issue 30: the decision stage (vision.decide) and the context a lasercal photo has: the rule's
parts, the dominance with any number of spots, the search region and the predicted position."""

from __future__ import annotations

import numpy as np
import pytest

from lasercal.vision.decide import RULE, DecisionRule, judge, margin
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import SpotCountError
from lasercal.vision.render import PhoneCamera, Photo, look_down, render, tilted_spot
from lasercal.vision.spot import Evidence

VIEW = look_down((240, 160), 0.3, centre=(450.0, 0.0))


def evidence(shift, white=0, clipped=0, lit=2.0, colour="red"):
    return Evidence(colour, 0.5, 50, 1.0, 0.4, None, clipped, white, 200, 0.0, 5.0, 1.0, shift, lit=lit)


def test_core_rule_takes_a_clipped_white_core_with_a_faint_fringe_and_nothing_whiter():
    rule = DecisionRule(shift_min=2.1, core_shift_min=1.8)
    core = judge(evidence(1.9, white=30, clipped=40), rule)
    rim = judge(evidence(3.0, white=30, clipped=40), rule)
    assert core.rule == "core" and rim.rule == "rim" and core.confidence < rim.confidence
    # The same faint fringe without a white core, or a whiter rim around one, is not laser light.
    assert judge(evidence(1.9), rule).rule is None
    assert judge(evidence(1.5, white=30, clipped=40), rule).rule is None
    # The probability rises with the margin and with clipping.
    assert margin(evidence(4.0), rule) > margin(evidence(3.0), rule) > 0
    assert rule.probability(0.5, True) > rule.probability(0.5, False)
    assert 0 < judge(evidence(20.0, 30, 40), RULE).confidence < 1


def two_spots(flux_ratio, seed=0):
    """A phone photo with two red spots, the second ``flux_ratio`` times the first's light."""
    spots = (
        tilted_spot(70.3, 80.6, 2.5, 10.0, 0, 0, speckle=0.1),
        tilted_spot(170.4, 80.2, 2.5, 10.0 * flux_ratio, 0, 0, speckle=0.1),
    )
    return render(Photo(VIEW, spots=spots, colour="red", paper=0.5, camera=PhoneCamera()), seed)


def near(spots, u, v):
    return [s for s in spots if np.hypot(s.u - u, s.v - v) < 2]


def test_with_any_number_expected_far_weaker_spots_are_left_out_and_named():
    img = two_spots(1.0)
    spots, _ = detect_spots(img, colour="auto", luma=True, expect=None)
    assert len(spots) == 2  # two alike: both kept
    img = two_spots(0.02)
    spots, warnings = detect_spots(img, colour="auto", luma=True, expect=None)
    assert len(spots) == 1 and near(spots, 70.3, 80.6)
    assert any("far weaker than the strongest" in w and "--reference" in w for w in warnings)


def test_the_search_region_and_the_predicted_position_pick_the_spot():
    img = two_spots(1.0)
    with pytest.raises(SpotCountError, match="--reference"):  # two alike, one expected: ambiguous
        detect_spots(img, colour="auto", luma=True, expect=1)
    right = np.array([[120, 0], [239, 0], [239, 159], [120, 159]], float)
    spots, _ = detect_spots(img, colour="auto", luma=True, expect=1, search=right)
    assert len(spots) == 1 and near(spots, 170.4, 80.2)
    spots, _ = detect_spots(img, colour="auto", luma=True, expect=1, predicted=(75.0, 78.0, 10.0))
    assert len(spots) == 1 and near(spots, 70.3, 80.6)
