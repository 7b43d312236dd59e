"""Spot detection and the precise centroid, against the renderer's known truth (px)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lasercal.vision.detect import detect_spots, find_candidates
from lasercal.vision.errors import NoSpotError, SpotCountError
from lasercal.vision.render import Glare, LaserSpot, Photo, cross_print, ink_dot, look_down, render

VIEW = look_down((320, 240), 0.3, centre=(450.0, 0.0))
SENSOR = dict(paper=0.5, gradient=0.2, vignetting=0.1)
HARSH = dict(paper=0.5, jpeg=90, bloom=0.3, gamma=2.2, gradient=0.2)


def errors(spot_kw, photo_kw, n, seed=0):
    """(n, 2) centroid errors of single spots at random sub-pixel places, px."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        u, v = rng.uniform(130, 190), rng.uniform(90, 150)
        img = render(Photo(VIEW, spots=(LaserSpot(u, v, **spot_kw),), **photo_kw), seed * 1000 + i)
        spots, _ = detect_spots(img)
        assert len(spots) == 1
        out.append([spots[0].u - u, spots[0].v - v])
    return np.array(out)


def rms(e):
    return float(np.sqrt(np.mean(e**2)))


def test_clean_unsaturated_spot_within_005_px():
    e = errors(dict(sigma=2.0, peak=0.4), dict(paper=0.5), 25)
    assert rms(e) < 0.05
    assert np.abs(e.mean(0)).max() < 0.02  # no bias


def test_saturated_spot_is_not_biased_by_clipping():
    # An elliptical, strongly clipped spot: the clipped plateau stays symmetric.
    e = errors(dict(sigma=2.5, peak=6.0, aspect=0.6, angle_deg=30), dict(paper=0.5, bloom=0.3), 20, seed=1)
    assert rms(e) < 0.05


def test_saturated_speckled_jpeg_spot_within_015_px():
    e = errors(dict(sigma=2.0, peak=3.0, speckle=0.3), HARSH, 25, seed=2)
    assert rms(e) < 0.15


def test_speckle_is_the_limit_error_grows_with_it():
    low = rms(errors(dict(sigma=2.0, peak=3.0, speckle=0.1), HARSH, 20, seed=3))
    high = rms(errors(dict(sigma=2.0, peak=3.0, speckle=0.8), HARSH, 20, seed=3))
    assert high > 1.5 * low


def test_reported_uncertainty_matches_the_error_within_a_factor_15():
    # Clean and strongly speckled (0.4, on the red channel of a 4:2:0 JPEG): the sigma was ~2x
    # under-reported there when it came from the data's own asymmetry.
    rng = np.random.default_rng(4)
    ratios = []
    for kw, pk in [
        (dict(sigma=2.0, peak=0.4), dict(paper=0.5)),
        (dict(sigma=2.0, peak=3.0, speckle=0.4), HARSH),
    ]:
        e, s = [], []
        for i in range(20):
            u, v = rng.uniform(130, 190), rng.uniform(90, 150)
            sp = detect_spots(render(Photo(VIEW, spots=(LaserSpot(u, v, **kw),), **pk), i))[0][0]
            e += [sp.u - u, sp.v - v]
            s += [sp.sigma_u, sp.sigma_v]
        ratios.append(rms(np.array(e)) / rms(np.array(s)))
    assert all(1 / 1.5 < r < 1.5 for r in ratios), ratios


@settings(max_examples=15, deadline=None)
@given(st.floats(100, 220), st.floats(80, 160), st.floats(1.2, 4.0), st.floats(0.3, 5.0))
def test_any_subpixel_centre_size_and_brightness(u, v, sigma, peak):
    img = render(Photo(VIEW, spots=(LaserSpot(u, v, sigma, peak),), **SENSOR), 7)
    s = detect_spots(img)[0][0]
    err = np.hypot(s.u - u, s.v - v)
    # the distance of a 2-D Gaussian error is Rayleigh: beyond 3.5 hypot(sigma_u, sigma_v) = 4.95 sigma in
    # exp(-4.95^2 / 2) = 5e-6 of draws (15 examples: 1e-4 a run); 3 hypot failed 2e-3 of runs
    assert err < 0.2 and err < 0.03 + 3.5 * np.hypot(s.sigma_u, s.sigma_v)
    # Paper is at ~0.5 of full scale in the red channel: the spot clips from peak ~0.5 on.
    if peak > 0.7 or peak < 0.35:
        assert s.saturated == (peak > 0.7)


def test_saturated_flag_peak_and_area():
    bright = detect_spots(render(Photo(VIEW, spots=(LaserSpot(160, 120, 2.0, 4.0),), paper=0.5), 0))[0][0]
    dim = detect_spots(render(Photo(VIEW, spots=(LaserSpot(160, 120, 2.0, 0.3),), paper=0.5), 0))[0][0]
    assert bright.saturated and bright.peak == 255
    assert not dim.saturated and 0.5 * 255 < dim.peak < 255
    assert bright.area > dim.area > 5


def test_many_spots_in_one_photo_are_all_found():
    truth = [(60.3, 50.7), (250.1, 60.2), (160.5, 120.4), (70.8, 190.1), (260.6, 185.9)]
    img = render(
        Photo(VIEW, spots=tuple(LaserSpot(u, v, 2.0, 2.0, speckle=0.2) for u, v in truth), **HARSH), 1
    )
    spots, warnings = detect_spots(img, expect=None)
    assert len(spots) == 5 and not warnings
    got = np.array([[s.u, s.v] for s in spots])
    for u, v in truth:
        assert np.min(np.hypot(*(got - [u, v]).T)) < 0.2


def test_two_spots_where_one_is_expected_is_an_error_naming_the_photo():
    img = render(
        Photo(VIEW, spots=(LaserSpot(80, 80, 2.0, 2.0), LaserSpot(240, 160, 2.0, 2.0)), paper=0.5), 0
    )
    with pytest.raises(SpotCountError, match=r"p\.jpg: 2 spots found where 1 is expected"):
        detect_spots(img, name="p.jpg", expect=1)
    spots, warnings = detect_spots(img, expect=3)
    assert len(spots) == 2 and "2 spots found where 3 are expected" in warnings[0]


def test_a_far_weaker_second_spot_is_named_not_chosen():
    # One laser adds about the same light wherever it lands: a candidate with a tenth of the
    # light is not the laser, and is named in a warning rather than making the photo ambiguous.
    strong, weak = LaserSpot(80.3, 80.6, 2.5, 6.0), LaserSpot(240.4, 160.2, 1.5, 0.6)
    img = render(Photo(VIEW, spots=(strong, weak), paper=0.5), 0)
    spots, warnings = detect_spots(img, name="p.jpg", expect=1)
    assert len(spots) == 1 and np.hypot(spots[0].u - 80.3, spots[0].v - 80.6) < 0.2
    assert "weaker candidates: (240." in warnings[0] and "confidence" in warnings[0]


def test_no_spot_is_an_error():
    img = render(Photo(VIEW, prints=(cross_print((450, 0), 12),), paper=0.5, jpeg=90, gamma=2.2), 0)
    with pytest.raises(NoSpotError, match=r"empty\.jpg: no red laser spot found"):
        detect_spots(img, name="empty.jpg")


def test_white_reflection_and_red_ink_are_rejected():
    prints = (ink_dot((440, 10), 5.0), cross_print((460, -10), 12), ink_dot((470, 12), 3.0))
    img = render(
        Photo(
            VIEW,
            prints=prints,
            spots=(LaserSpot(130.4, 160.2, 2.0, 3.0, speckle=0.2),),
            glares=(Glare(250, 60, 5, 3.0), Glare(60, 60, 3, 1.5)),
            **HARSH,
        ),
        3,
    )
    spots, _ = detect_spots(img)
    assert len(spots) == 1 and np.hypot(spots[0].u - 130.4, spots[0].v - 160.2) < 0.2
    only_glare = render(Photo(VIEW, prints=prints, glares=(Glare(250, 60, 5, 3.0),), **HARSH), 3)
    with pytest.raises(NoSpotError, match="rejected"):
        detect_spots(only_glare)


def test_reference_photo_makes_a_faint_spot_on_clutter_measurable():
    prints = (cross_print((440, 5), 12), ink_dot((470, -10), 4.0))
    off = render(Photo(VIEW, prints=prints, **HARSH), 11)
    u, v = 171.3, 101.8
    on = render(Photo(VIEW, prints=prints, spots=(LaserSpot(u, v, 2.0, 0.15),), **HARSH), 12)
    with pytest.raises(NoSpotError):
        detect_spots(on)  # too faint to tell from JPEG fringes at the ink without a reference
    s = detect_spots(on, reference=off)[0][0]
    assert np.hypot(s.u - u, s.v - v) < 0.5


def test_green_laser():
    img = render(Photo(VIEW, spots=(LaserSpot(150.25, 110.75, 2.0, 2.0),), colour="green", **SENSOR), 0)
    s = detect_spots(img, colour="green")[0][0]
    assert np.hypot(s.u - 150.25, s.v - 110.75) < 0.05
    with pytest.raises(NoSpotError):
        detect_spots(img, colour="red")


def test_grey_and_16_bit_photos():
    img = render(Photo(VIEW, spots=(LaserSpot(150.4, 110.6, 2.0, 0.4),), paper=0.5), 0)
    grey = img[..., 2].copy()
    s, w = detect_spots(grey)
    assert np.hypot(s[0].u - 150.4, s[0].v - 110.6) < 0.06 and "grey photo" in w[0]
    deep = img.astype(np.uint16) * 257
    s16 = detect_spots(deep)[0][0]
    assert np.hypot(s16.u - 150.4, s16.v - 110.6) < 0.06 and s16.peak > 256


def test_candidates_on_a_large_photo_are_few_and_include_the_spot():
    view = look_down((2000, 1500), 0.3, centre=(450.0, 0.0))
    img = render(
        Photo(
            view, prints=(cross_print((450, 0), 12),), spots=(LaserSpot(1500.5, 300.5, 2.0, 2.0),), **HARSH
        ),
        0,
    )
    cands = find_candidates(img)
    assert 1 <= len(cands) <= 3
    assert any(c.box[0] <= 1500 < c.box[2] and c.box[1] <= 300 < c.box[3] for c in cands)


def test_opencv_and_imagej_conventions():
    s = detect_spots(render(Photo(VIEW, spots=(LaserSpot(150.0, 110.0, 2.0, 0.4),), paper=0.5), 0))[0][0]
    a, b = s.to_dict("opencv"), s.to_dict("imagej")
    assert b["u"] - a["u"] == pytest.approx(0.5) and b["v"] - a["v"] == pytest.approx(0.5)
    assert abs(a["u"] - 150.0) < 0.05


def test_spot_on_a_printed_cross_is_found_and_flagged():
    # Aiming at a printed reference cross puts ink under the spot: it must still be found,
    # and flagged, since ink swallows light unevenly (see README: a few tenths of a pixel).
    errs = []
    for i, off in enumerate([(0.0, 0.0), (0.3, 2.5), (2.5, -0.3)]):
        centre = np.array([449.0 + i, 1.0 - i])
        uv = VIEW.project(centre + off)[0]
        img = render(
            Photo(
                VIEW,
                prints=(cross_print(centre, 12, 0.5),),
                spots=(LaserSpot(*uv, 2.5, 4.0, speckle=0.2),),
                **HARSH,
            ),
            i,
        )
        spots, warnings = detect_spots(img)
        assert len(spots) == 1 and spots[0].on_ink and "printed ink" in warnings[0]
        errs.append(np.hypot(spots[0].u - uv[0], spots[0].v - uv[1]))
    assert max(errs) < 0.6
    clear = detect_spots(
        render(
            Photo(
                VIEW, prints=(cross_print((430, -20), 12),), spots=(LaserSpot(160, 120, 2.5, 4.0),), **HARSH
            ),
            0,
        )
    )
    assert not clear[0][0].on_ink and not clear[1]


def test_luma_centroid_beats_the_red_channel_on_chroma_subsampled_jpeg():
    # JPEG keeps colour at half resolution: the red channel is rebuilt from it, the luma is not.
    rng = np.random.default_rng(8)
    err = {False: [], True: []}
    for i in range(20):
        u, v = rng.uniform(130, 190), rng.uniform(90, 150)
        img = render(
            Photo(VIEW, spots=(LaserSpot(u, v, 2.0, 3.0),), paper=0.5, jpeg=90, gamma=2.2, bloom=0.3), i
        )
        for luma in err:
            s = detect_spots(img, luma=luma)[0][0]
            err[luma].append(np.hypot(s.u - u, s.v - v))
    assert rms(np.array(err[True])) < 0.06 and rms(np.array(err[True])) < 0.7 * rms(np.array(err[False]))
