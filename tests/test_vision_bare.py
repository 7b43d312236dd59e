"""Issue 55: the outside check's last misses and false spots on photos from other cameras, rendered with
known truth (``vision.render_wild.SCENES_55``): a spot so overexposed that its colour is gone is read
when it is the photo's only compact white clipped blob, and refused with the reason when there are
several; a clipped core that a streak leans is centred on the rim of its saturation; a red object is not
chosen over a spot; a red-lit edge beside a spot is no second spot."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from lasercal.vision.bare import rim_centre
from lasercal.vision.decide import RULE, DecisionRule, judge, refusal
from lasercal.vision.errors import NoSpotError
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.render import Glare, PhoneCamera, Photo, look_down, render
from lasercal.vision.render_wild import SCENES_55, two_white_cores
from lasercal.vision.spot import Evidence

SEEDS = range(6)  # the benchmark scores seeds 100-119 (benchmarks/bench_vision_wild.py)


def reported(img):
    """What ``lasercal spots --json --expect any`` reports for a phone JPEG, and its error line."""
    try:
        return measure_photo(img, "x", Options(expect=None), subsampled=True).spots, ""
    except NoSpotError as exc:
        return [], str(exc)


@pytest.fixture(scope="module")
def scored():
    """Per kind: found (within 4 px of the truth), false (farther than 3 x core radius + 6 px), the
    distances of the found spots, px, and the error lines."""
    out = {}
    for kind, draw in dict(SCENES_55, **{"two white cores": two_white_cores}).items():
        found, false, near, said = 0, 0, [], []
        for seed in SEEDS:
            sc = draw(seed)
            spots, line = reported(sc.img)
            d = [float(np.hypot(s.u - sc.truth[0], s.v - sc.truth[1])) for s in spots]
            hit = [x for x in d if x <= 4.0]
            found += bool(hit)
            near += [min(hit)] if hit else []
            false += sum(x > 3 * sc.radius + 6 for x in d)
            said.append(line)
        out[kind] = found, false, near, said
    return out


def test_a_colourless_core_alone_in_the_photo_is_read(scored):
    # Before issue 55, 3 of these 6 were refused as "a laser spot so overexposed that its colour is gone"
    # (rim shift 1.09-1.44: white light measures up to ~1.06). Now 5 (the sixth's rim measures 1.09).
    found, false, near, _ = scored["colourless core"]
    assert found >= 5 and false == 0, (found, false)
    assert max(near) < 0.5


def test_several_colourless_cores_are_refused_with_the_reason(scored):
    # The same scenes with a second white clipped blob of the spot's size: which is the laser the photo
    # cannot say. No spot but the true one is ever reported, and where none is, the refusal says why.
    found, false, _, said = scored["two white cores"]
    assert false == 0
    assert any("several alike" in line for line in said), said


def test_a_leaning_clipped_core_is_found(scored):
    # The rim centring (vision.bare.RIM_STRAY) is off by default: it cost the phone sweep's clipped red
    # spots (see the next test). The leaning cores are found, 1.5-4 px off.
    found, false, near, _ = scored["leaning core"]
    assert found >= len(SEEDS) - 1 and false == 0


def test_the_rim_centres_a_leaning_core_when_turned_on(monkeypatch):
    # A flare streak joined to the core on one side pulls the fit 1.5-4.0 px towards it (median 2.4 px on
    # these seeds); with the rim centring on at 0.75 px the median falls under 1.2 px.
    from lasercal.vision import detect

    monkeypatch.setattr(detect, "RIM_STRAY", 0.75)
    near = []
    for seed in SEEDS:
        sc = SCENES_55["leaning core"](seed)
        spots, _ = reported(sc.img)
        near.append(min(float(np.hypot(s.u - sc.truth[0], s.v - sc.truth[1])) for s in spots))
    assert np.median(near) < 1.2 and max(near) < 2.5, near


def test_a_red_object_is_not_a_second_spot(scored):
    # Before issue 55 the red object (its red clipped over a flat top, its other channels below the
    # surface's) was reported beside the spot on seed 2, and outshone it in flux.
    found, false, _, _ = scored["red object"]
    assert found == len(SEEDS) and false == 0, (found, false)


def test_a_red_lit_edge_is_not_a_second_spot(scored):
    found, false, _, _ = scored["red-lit edge"]
    assert found == len(SEEDS) and false <= 1, (found, false)


def test_rim_centre_ignores_a_streak_joined_to_the_core():
    # A disc of radius 10 px at (40.3, 50.6) with a 5-px-wide streak 16 px long on its right: the mean of
    # the clipped pixels leans ~2 px towards the streak, the rim's centre stays on the disc.
    yy, xx = np.mgrid[:100, :100]
    mask = np.hypot(xx - 40.3, yy - 50.6) <= 10
    mask |= (xx >= 45) & (xx <= 66) & (np.abs(yy - 50.6) <= 2.5)
    u, v = rim_centre(mask, (40, 50))
    mean = xx[mask].mean()
    assert mean - 40.3 > 1.5
    assert np.hypot(u - 40.3, v - 50.6) < 0.4
    # A clean disc or ellipse does not lean: it is left to the precise fit.
    assert rim_centre(np.hypot(xx - 60.7, yy - 30.2) <= 8, (60, 30)) is None
    assert rim_centre(np.hypot((xx - 60.7) / 2, yy - 30.2) <= 6, (60, 30)) is None


def white_core(shift, bare, white=300, clipped=320):
    return Evidence(
        "red", 0.3, 60, 1.0, 0.3, None, clipped, white, 400, 0.0, 1.0, 1.0, shift, lit=2.0, bare=bare
    )


def test_the_bare_rule_needs_a_laser_ward_rim_and_no_peer():
    rule = DecisionRule(bare_shift=1.15)
    assert judge(white_core(1.3, 1), rule).rule == "bare"
    assert judge(white_core(1.3, 1), rule).confidence < 0.5  # reported with a low probability
    assert judge(white_core(1.05, 1), rule).rule is None  # white light: no rim colour
    assert judge(white_core(1.3, None), rule).rule is None  # not counted: not a white blob of a core's size
    several = judge(white_core(1.3, 3), rule)
    assert several.rule is None and refusal(white_core(1.3, 3), rule) == "several"
    assert refusal(white_core(1.05, 3), rule) == "white"


def test_a_lone_white_glare_is_no_spot():
    # The rule's other half: a clipped white glare alone on a grey sheet under room light (the photo a
    # colourless core is read in, without the laser) measures no laser-ward rim and is never read.
    view = look_down((640, 480), 0.1, centre=(450.0, 0.0))
    for seed, (peak, sigma) in enumerate([(30, 4), (100, 6), (300, 3)]):
        photo = Photo(
            view,
            glares=(Glare(300.0, 220.0, sigma=sigma, peak=peak),),
            paper=0.4,
            tint=(0.9, 0.96, 1.0),
            camera=PhoneCamera(
                bloom=0.7, jpeg=90, ae_target=None, ae_stops=0.0, highlight=0.9, chroma_blur=2
            ),
        )
        spots, _ = reported(render(photo, seed))
        assert spots == [], (seed, [(s.u, s.v, s.evidence.rule) for s in spots])


def test_rule_defaults_are_the_fitted_ones():
    assert RULE.bare_shift >= 1.1 and 0.3 <= RULE.adds_share <= 0.9


def test_a_clipped_core_mask_cut_to_a_box_is_measured():
    # rim_centre on a core touching its box's edge still returns a point inside the box.
    mask = np.zeros((30, 30), bool)
    cv2.circle(mask.view(np.uint8), (2, 15), 8, 1, -1)
    cv2.rectangle(mask.view(np.uint8), (8, 14), (20, 16), 1, -1)  # a streak: the core leans
    c = rim_centre(mask, (2, 15))
    assert c is not None and 0 <= c[1] < 30 and c[0] < 5
