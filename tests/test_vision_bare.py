"""Issue 55: the outside check's last misses and false spots on photos from other cameras, rendered with
known truth (``vision.render_wild.SCENES_55``): a spot so overexposed that its colour is gone is read
when it is the photo's only compact white clipped blob, and refused with the reason when there are
several; a clipped core that a streak leans is centred on the rim of its saturation; a red object is not
chosen over a spot; a red-lit edge beside a spot is no second spot."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from scipy.stats import binom

from lasercal.vision.bare import lopsided, rim_centre
from lasercal.vision.decide import RULE, DecisionRule, judge, refusal
from lasercal.vision.detect import _laser_like, _point_symmetric, detect_spots, measure_candidates, select
from lasercal.vision.errors import NoSpotError
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.render import Glare, PhoneCamera, Photo, look_down, render, tilted_spot
from lasercal.vision.render_wild import SCENES_55, two_white_cores
from lasercal.vision.spot import Evidence, Spot

# Scored on seeds nothing was chosen on: the thresholds of issue 55 (vision.fit.ISSUE_55) are fitted on
# seeds 0-7 of each kind (benchmarks/bench_vision_wild_loso.py), and the bounds below are quantiles of a
# count over these 6 seeds, from each kind's per-photo rates measured on the fresh seeds 200-239 by the
# same benchmark ("RULE as it stands" rows): a count of 6 photos is Binomial(6, rate), and a bound is its
# 0.1 % (found) or 99.9 % (false spots) quantile, so that a borderline photo flipped by another CPU's
# rounding fails the test at most 1 in 1,000. A rate measured as 0 (or 1) on 40 seeds gives the bound 0 (or
# 6): its true rate is below 3/40 (95 %).
SEEDS = range(1000, 1006)
# Per kind, (found, false spots) per photo on the fresh seeds 200-239 under RULE.
RATE = {
    "colourless core": (34 / 40, 0 / 40),
    "leaning core": (40 / 40, 0 / 40),
    "red object": (40 / 40, 1 / 40),
    "red-lit edge": (40 / 40, 0 / 40),
}
# px: the 99.9 % quantile of the median distance of 6 found leaning cores, resampled (200,000 times) from
# the 40 of the fresh seeds (0.14-3.44 px, median 1.53 px).
NEAR_LEAN = 2.9


def bound(rate: float, lower: bool) -> int:
    """The 0.1 % (lower) or 99.9 % quantile of Binomial(len(SEEDS), rate)."""
    return int(binom.ppf(0.001 if lower else 0.999, len(SEEDS), rate))


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
    # Before issue 55 half of these were refused as "a laser spot so overexposed that its colour is gone"
    # (rim shift 1.09-1.44: white light measures up to ~1.06). Fresh seeds 200-239: 34 of 40, 0 false.
    found, false, near, _ = scored["colourless core"]
    assert found >= bound(RATE["colourless core"][0], True) and false == 0, (found, false)
    assert max(near) < 0.5


def test_several_colourless_cores_are_refused_with_the_reason(scored):
    # The same scenes with a second white clipped blob of the spot's size: which is the laser the photo
    # cannot say. No spot but the true one is ever reported (fresh seeds: 0 false in 40), and where none
    # is, the refusal says why.
    found, false, _, said = scored["two white cores"]
    assert false == 0
    assert any("several alike" in line for line in said), said


def test_a_leaning_clipped_core_is_found(scored):
    # A flare streak joined to the core on one side pulls the precise fit 1-4.2 px towards it (fresh
    # seeds, the rim off: 36 of 40 found, median 2.14 px; on: 40 of 40, 1.53 px).
    found, false, near, _ = scored["leaning core"]
    assert found >= bound(RATE["leaning core"][0], True) and false == 0, (found, false)
    assert np.median(near) < NEAR_LEAN, near


def test_a_lopsided_clipped_core_is_centred_on_its_rim():
    # Where the core's light is lopsided (at least RULE.lean_min) and the fit strays from the rim of the
    # saturation, the spot is reported at the rim's centre, nearer the beam than the fit.
    moved = 0
    for seed in SEEDS:
        sc = SCENES_55["leaning core"](seed)
        tries = measure_candidates(sc.img, "auto", None, 2.2, True)
        on = select(tries, "x", None, RULE)[1]
        off = select(tries, "x", None, replace(RULE, lean_min=np.inf))[1]
        (a,), (b,) = on, off
        ev = a.evidence
        if (a.u, a.v) != (b.u, b.v):
            moved += 1
            assert ev.lopsided >= RULE.lean_min and (a.u, a.v) == pytest.approx(ev.rim_centre)
            assert np.hypot(a.u - sc.truth[0], a.v - sc.truth[1]) < np.hypot(
                b.u - sc.truth[0], b.v - sc.truth[1]
            )
    assert moved >= 1


def test_a_red_object_is_not_a_second_spot(scored):
    # Before issue 55 the red object (its red clipped over a flat top, its other channels below the
    # surface's) was reported beside the spot, and outshone it in flux.
    found, false, _, _ = scored["red object"]
    rate_found, rate_false = RATE["red object"]
    assert found >= bound(rate_found, True) and false <= bound(rate_false, False), (found, false)


def test_a_red_lit_edge_is_not_a_second_spot(scored):
    # Before the lopsidedness (issue 55), 6 of 20 fresh seeds reported the lit edge as a second spot.
    found, false, _, _ = scored["red-lit edge"]
    rate_found, rate_false = RATE["red-lit edge"]
    assert found >= bound(rate_found, True) and false <= bound(rate_false, False), (found, false)


def far_and_found(sc, tries, rule) -> tuple[int, bool]:
    """A scene's false spots under ``rule``, and whether its spot is found."""
    d = [np.hypot(s.u - sc.truth[0], s.v - sc.truth[1]) for s in select(tries, "x", None, rule)[1]]
    return sum(x > 3 * sc.radius + 6 for x in d), any(x <= 4 for x in d)


def test_a_red_lit_edge_taken_for_a_spot_before_is_refused_now():
    # The photos where the lit edge is a spot but for its lopsidedness (RULE with lopsided_max off reports
    # it): the first 3 from seed 1000 on. On the fresh seeds 200-239, 6 such photos: RULE reported no
    # false spot in any and found the spot in each (the bound: 0 false, 3 found).
    hard = 0
    for seed in range(1000, 1100):
        sc = SCENES_55["red-lit edge"](seed)
        tries = measure_candidates(sc.img, "auto", None, 2.2, True)
        if far_and_found(sc, tries, replace(RULE, lopsided_max=np.inf))[0]:
            assert far_and_found(sc, tries, RULE) == (0, True), seed
            hard += 1
            if hard == 3:
                break
    assert hard == 3


def test_of_several_candidates_a_red_object_is_refused_by_its_light():
    # A red object's luma rises 0.35-0.83 of its red's on the renders (its other channels below the
    # surface's), the spots' 0.95-0.99 beside it, the shared photos' 0.81-1.47: under RULE.adds_share
    # (0.85) of the most laser-like, refused with the reason.
    def spot(u, light):
        ev = Evidence("red", 0.5, 60, 1.0, light, None, 50, 10, 400, 0.8, 1.0, 1.0, 10.0)  # whitened cores
        return Spot(u, 50.0, 0.1, 0.1, 255.0, True, 400, evidence=ev)

    kept, note = _laser_like([spot(10, 0.49), spot(90, 0.40)], RULE.adds_share)
    assert [s.u for s in kept] == [10] and "colour the photo more than they light it" in note
    # Against spots clipped in their own channel alone (no white pixel) nothing is refused: such lasers
    # rise 0.46-0.62 (tests/test_vision_plane.py's three in one photo).
    plain = [replace(s, evidence=replace(s.evidence, white_px=0)) for s in (spot(10, 0.49), spot(90, 0.40))]
    assert _laser_like(plain, RULE.adds_share) == (plain, None)


def test_a_lopsided_lamp_is_no_yardstick_for_a_spot_clipped_in_red():
    # A lamp's white clipped core, its red glow cut by an edge, adds 0.99 of its red in luma; a true spot
    # clipped in red alone beside it 0.73 (a rendered lamp at an edge, issue 47's wild scenes). Measured
    # against the lamp the spot was refused as "colouring the photo" and the lamp then reported; the lamp
    # is no beam (0.24 lopsided, the spot 0.06), so it is no yardstick, and the point symmetry refuses it.
    def cand(u, light, white, lop):
        ev = Evidence("red", 1.0, 60, 1.0, light, None, 50, white, 400, 0.8, 1.0, 1.0, 10.0, lopsided=lop)
        return Spot(u, 50.0, 0.1, 0.1, 255.0, True, 400, evidence=ev)

    lamp, spot = cand(10, 0.99, 160, 0.24), cand(90, 0.73, 0, 0.06)
    assert _laser_like([lamp, spot], RULE.adds_share, most=RULE.lopsided_max) == ([lamp, spot], None)
    assert _point_symmetric([lamp, spot], RULE.lopsided_max)[0] == [spot]
    # A point-symmetric whitened spot stays the yardstick: a red object beside it is refused.
    white_spot, red = cand(10, 0.97, 50, 0.05), cand(90, 0.45, 0, 0.04)
    assert _laser_like([white_spot, red], RULE.adds_share, most=RULE.lopsided_max)[0] == [white_spot]
    # Where every candidate is lopsided (a small spot on a real surface measures 0.2 of it) the point
    # symmetry tells none apart, and the most laser-like one is the yardstick, as before: an orange object
    # rising 0.81 beside a spot rising 0.97 is refused.
    small, orange = cand(10, 0.97, 7, 0.23), cand(90, 0.81, 0, 0.59)
    assert _laser_like([small, orange], RULE.adds_share, most=RULE.lopsided_max)[0] == [small]


def test_a_beams_light_is_point_symmetric_and_a_cut_glow_is_not():
    # An elliptical Gaussian spot, clipped or not, turned half round about its centre lands on itself (up
    # to the bilinear interpolation: under 0.02); the same light cut by a dark object 2 px past its
    # centre is 0.23-0.30 lopsided, far over RULE.lopsided_max.
    yy, xx = np.mgrid[:120, :160]
    for sigma, peak in [(3, 2.0), (6, 4.0), (10, 1.0)]:
        g = np.exp(-((xx - 80.3) ** 2 / (2 * sigma**2) + (yy - 60.6) ** 2 / (2 * (0.6 * sigma) ** 2)))
        img = np.full((120, 160, 3), 60, np.uint8)
        img[..., 2] = np.clip(60 + 200 * peak * g, 0, 255)
        assert lopsided(img, 2, 80.3, 60.6, (g * peak > 0.1).sum()) < 0.02
        img[:, 82:] = 5
        e = np.maximum(img[..., 2] - 60.0, 0)
        u, v = (e * xx).sum() / e.sum(), (e * yy).sum() / e.sum()
        assert lopsided(img, 2, u, v, (e > 20).sum()) > 2 * RULE.lopsided_max


def test_of_several_candidates_a_lopsided_one_is_refused_with_the_reason():
    def spot(u, lop, cut=False):
        ev = Evidence("red", 0.3, 60, 1.0, 0.3, None, 50, 0, 400, 0.8, 1.0, 1.0, 10.0, lopsided=lop, cut=cut)
        return Spot(u, 50.0, 0.1, 0.1, 255.0, True, 400, evidence=ev)

    kept, note = _point_symmetric([spot(10, 0.04), spot(90, 0.3)], RULE.lopsided_max)
    assert [s.u for s in kept] == [10] and "several candidates" in note and "(90.0, 50.0)" in note
    # Alone, or when every candidate is lopsided, or cut by the photo's edge: nothing to choose by it.
    assert _point_symmetric([spot(10, 0.3), spot(90, 0.3)], RULE.lopsided_max) == (
        [spot(10, 0.3), spot(90, 0.3)],
        None,
    )
    assert _point_symmetric([spot(10, 0.04), spot(90, 0.3, cut=True)], RULE.lopsided_max)[1] is None


def test_a_round_clipped_phone_spot_keeps_its_precise_fit():
    # The rim centres only a lopsided core: the phone sweep's clipped spots (240 photos at 1-30x, red and
    # green, speckle 0 and 0.1; 320 x 240 JPEG 4:2:0) measure 0.04-0.11, under RULE.lean_min, and keep
    # the precise fit (with the rim's gate at 0.1 one of them moved 0.86 px, and its row's RMS
    # tripled).
    view = look_down((200, 160), 0.3, centre=(450.0, 0.0))
    for seed in range(8):
        rng = np.random.default_rng([seed, 55])
        u, v = rng.uniform(80, 120, 2)
        spot = tilted_spot(
            u, v, rng.uniform(1.5, 3.0), 10.0, rng.uniform(0, 40), rng.uniform(0, 180), speckle=0.1
        )
        img = render(Photo(view, spots=(spot,), paper=rng.uniform(0.4, 0.6), camera=PhoneCamera()), seed)
        (s,), _ = detect_spots(img, colour="auto", luma=True)
        assert s.saturated and s.evidence.lopsided < RULE.lean_min, (seed, s.evidence.lopsided)
        assert np.hypot(s.u - u, s.v - v) < 0.3


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


def white_core(shift, bare, white=300, clipped=320, paper=1.0):
    return Evidence(
        "red",
        0.3,
        60,
        1.0,
        0.3,
        None,
        clipped,
        white,
        400,
        0.0,
        shift * paper,
        paper,
        shift,
        lit=2.0,
        bare=bare,
    )


def test_the_bare_rule_needs_a_laser_ward_rim_and_no_peer():
    rule = DecisionRule(bare_shift=1.15, bare_neutral=0.05)
    assert judge(white_core(1.3, 1), rule).rule == "bare"
    # On a coloured surface a warm lamp's clipped core shows as faint a laser-ward rim: not read.
    assert judge(white_core(1.3, 1, paper=0.7), rule).rule is None
    assert judge(white_core(1.3, 1, paper=1.04), rule).rule == "bare"
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


def test_a_camera_whose_balance_misses_leaves_the_grey_surface_off_neutral():
    # The renderer balances perfectly: the colourless core's grey surface reads a paper ratio of 1.00
    # (within the JPEG's rounding). A real camera's balance misses (render_wild.BALANCE_MISS: +-0.1 in the
    # red and blue gains), and the colour matrix after it widens the miss by its red row's red term less
    # its green row's (1.65 + 0.25: ln(R/G) of a grey moves 1.9 x the red gain's): colourless_off_balance's
    # surface reads off neutral, never farther than that.
    from lasercal.vision.render import PHONE_CCM
    from lasercal.vision.render_wild import BALANCE_MISS, colourless_core, colourless_off_balance

    widened = float(PHONE_CCM[2, 2] - PHONE_CCM[1, 2]) * BALANCE_MISS

    def off(draw, seed):  # |ln paper ratio| under the spot's rim, in the laser's colour
        sc = draw(seed)
        spots = measure_candidates(sc.img, "red", None, 2.2, True)["red"][0]
        s = min(spots, key=lambda s: np.hypot(s.u - sc.truth[0], s.v - sc.truth[1]))
        return abs(np.log(s.evidence.paper_ratio))

    balanced = [off(colourless_core, seed) for seed in SEEDS]
    missed = [off(colourless_off_balance, seed) for seed in SEEDS]
    assert max(balanced) <= 0.01, balanced
    assert max(missed) > 0.03 and max(missed) <= widened + 0.01, missed


def test_rule_defaults_are_the_fitted_ones():
    # What benchmarks/bench_vision_wild_loso.py fits on all shared photos and the development renders
    # (every leave-one-source-out fold fitted the same).
    fitted = dict(bare_shift=1.15, bare_neutral=0.01, adds_share=0.85, lopsided_max=0.1, lean_min=0.12)
    assert {k: getattr(RULE, k) for k in fitted} == fitted


def test_a_clipped_core_mask_cut_to_a_box_is_measured():
    # rim_centre on a core touching its box's edge still returns a point inside the box.
    mask = np.zeros((30, 30), bool)
    cv2.circle(mask.view(np.uint8), (2, 15), 8, 1, -1)
    cv2.rectangle(mask.view(np.uint8), (8, 14), (20, 16), 1, -1)  # a streak: the core leans
    c = rim_centre(mask, (2, 15))
    assert c is not None and 0 <= c[1] < 30 and c[0] < 5
