"""Issue 13: laser spots as a phone camera records them, against the renderer's truth (fixed seeds)."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from lasercal.vision import refine
from lasercal.vision.camera import Camera
from lasercal.vision.detect import SHIFT_MIN, detect_spots
from lasercal.vision.errors import NoSpotError
from lasercal.vision.exposure import exposure_advice
from lasercal.vision.measure import Options, measure_batch
from lasercal.vision.render import (
    Glare,
    LaserSpot,
    PhoneCamera,
    Photo,
    cross_print,
    ink_dot,
    look_down,
    render,
    tilted_spot,
)

VIEW = look_down((200, 160), 0.3, centre=(450.0, 0.0))
PHONE = PhoneCamera()
EXPOSURES = (0.3, 1.0, 3.0, 10.0, 30.0)  # the spot's peak light over the clipping level


def photo(colour, exposure, seed, speckle=0.2, sigma=None, tilt=None, **kw):
    """A phone photo of one spot at a random sub-pixel place; returns (truth u, v), image."""
    rng = np.random.default_rng([seed, int(exposure * 10), colour == "red"])
    u, v = rng.uniform(80, 120, 2)
    sigma = sigma or rng.uniform(1.5, 3.0)
    tilt = rng.uniform(0, 40) if tilt is None else tilt
    spot = tilted_spot(u, v, sigma, exposure, tilt, rng.uniform(0, 180), speckle=speckle)
    kw = {"paper": rng.uniform(0.4, 0.6), **kw}
    return (u, v), render(Photo(VIEW, spots=(spot,), colour=colour, camera=PHONE, **kw), seed)


def test_phone_renderer_records_a_white_core_in_a_coloured_halo():
    (u, v), img = photo("red", 30.0, 0, speckle=0, sigma=2.5, tilt=0)
    core = img[int(round(v)), int(round(u))].astype(int)
    assert (core >= 245).all()  # clipped white, as phones record it
    row = img[int(round(v)), int(round(u)) : int(round(u)) + 12].astype(int)  # out to ~5 sigma: the halo
    # Red (nearly) clipped, green and blue raised by blooming: pink.
    assert any(p[2] >= 240 and 25 < p[2] - max(p[:2]) < 100 for p in row)
    (u, v), dim = photo("red", 0.3, 0, speckle=0, sigma=2.5, tilt=0)
    assert dim.max() < 255 and dim[int(round(v)), int(round(u)), 2] > np.median(dim[..., 2]) + 20


def test_phone_auto_exposure_changes_between_photos_and_tilted_spots_are_elliptical():
    gains = [PHONE.gain(s) for s in range(6)]
    assert max(gains) / min(gains) > 1.3 and all(0.7 <= g <= 1.42 for g in gains)
    papers = [np.median(render(Photo(VIEW, paper=0.5, camera=PHONE), s)) for s in (0, 1, 2)]
    assert np.ptp(papers) > 5
    s = tilted_spot(10, 20, 2.0, 1.0, 60, 30)
    assert s.sigma == pytest.approx(4.0) and s.aspect == pytest.approx(0.5) and s.peak == pytest.approx(0.5)


@pytest.mark.parametrize("colour", ["red", "green"])
def test_every_spot_found_over_the_exposure_sweep_with_colour_auto(colour):
    # 0.3x to 30x the clipping level: dim spots, clipped pink/green halos, white cores with blooming.
    for exposure in EXPOSURES:
        for seed in range(4):
            (u, v), img = photo(colour, exposure, seed)
            spots, _ = detect_spots(img, colour="auto", luma=True)
            s = spots[0]
            assert len(spots) == 1 and s.evidence.colour == colour, (exposure, seed)
            assert np.hypot(s.u - u, s.v - v) < 0.5
            assert s.saturated == (s.evidence.clipped_px > 0)
            ev = s.evidence
            # The confidence is a probability calibrated over every candidate that passes the physical
            # gates (real clutter among them): a dim unclipped spot clears its rule with a low one.
            assert 0 < ev.confidence < 1 and ev.rim_shift >= SHIFT_MIN and ev.rule == "rim"
            if exposure >= 30:
                assert s.saturated and s.evidence.white_px > 0  # a white core, accepted by its halo


def centroid_errors(colour, exposures, n, speckle):
    e, s = [], []
    for exposure in exposures:
        for seed in range(n):
            (u, v), img = photo(colour, exposure, 100 + seed, speckle)
            sp = detect_spots(img, colour=colour, luma=True)[0][0]
            e.append([sp.u - u, sp.v - v])
            s.append([sp.sigma_u, sp.sigma_v])
    return np.array(e), np.array(s)


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.mark.parametrize("speckle", [0.0, 0.2])
@pytest.mark.parametrize("colour", ["red", "green"])
def test_clipped_spot_centre_within_030_px_and_its_sigma_within_15x(colour, speckle):
    # Speckle-free clipped spots are where the sigma was over-reported (~1.7x), speckled ones where
    # it was under-reported: honest within 1.5x in both.
    e, s = centroid_errors(colour, (3.0, 10.0, 30.0), 8, speckle)
    assert rms(e) < 0.10 and np.abs(e).max() < 0.3  # the bound is 0.30 px RMS
    assert 1 / 1.5 < rms(e) / rms(s) < 1.5


def test_unsaturated_green_spot_centre_within_010_px():
    e, s = centroid_errors("green", (0.3,), 16, speckle=0.1)
    assert rms(e) < 0.10
    assert 1 / 1.5 < rms(e) / rms(s) < 1.5


def test_unsaturated_red_spot_fitted_in_luma_plus_chroma(monkeypatch):
    # Colour correction leaves a dim red spot ~1/4 of its red rise in the luma, the only full-
    # resolution plane of a 4:2:0 JPEG, twice that in Cr: the fit's plane takes a fifth of Cr.
    e, s = centroid_errors("red", (0.3,), 16, speckle=0.0)
    assert rms(e) < 0.115 and 1 / 1.5 < rms(e) / rms(s) < 1.5
    monkeypatch.setattr(refine, "CHROMA_WEIGHT", 0.0)  # the luma alone, as before
    luma_only, _ = centroid_errors("red", (0.3,), 16, speckle=0.0)
    assert rms(e) < 0.85 * rms(luma_only)
    monkeypatch.undo()
    # Half the clipping level: within the goal of 0.10 px, with speckle.
    e, s = centroid_errors("red", (0.5,), 16, speckle=0.1)
    assert rms(e) < 0.10 and 1 / 1.5 < rms(e) / rms(s) < 1.5


def no_spot(img):
    with pytest.raises(NoSpotError) as info:
        detect_spots(img, colour="auto", luma=True, expect=None)
    return str(info.value)


@pytest.mark.parametrize("peak", [0.5, 3.0, 30.0])
def test_white_glare_is_rejected_with_its_evidence(peak):
    for seed, sigma in enumerate((2.0, 5.0)):
        img = render(Photo(VIEW, glares=(Glare(100.3, 80.6, sigma, peak),), paper=0.5, camera=PHONE), seed)
        msg = no_spot(img)
        assert "no red or green laser spot found" in msg
        if peak >= 30:  # the reason names the white blob and what to do if it was the laser
            assert "white clipped blob without laser colour" in msg and "lower the exposure" in msg
        if "white, not laser-coloured" in msg and "rim shift " in msg:
            shift = float(msg.split("rim shift ")[1].split(",")[0])
            assert shift < SHIFT_MIN


def test_red_and_green_ink_and_crosses_make_no_spots():
    # Colour correction lifts red ink's red above the paper's: the luma, which laser light raises, tells.
    prints = (
        ink_dot((440, 10), 5.0),
        ink_dot((465, -8), 3.0, (0.3, 0.7, 0.25)),
        cross_print((452, 6), 12),
        cross_print((438, -12), 8, 0.3),
    )
    for seed in range(3):
        no_spot(render(Photo(VIEW, prints=prints, paper=0.5 + 0.05 * seed, camera=PHONE), seed))
    # ... and a spot among them is found, in either colour.
    for colour in ("red", "green"):
        spot = tilted_spot(170.4, 130.3, 2.0, 3.0, 20, 0, speckle=0.2)  # away from the prints
        img = render(
            Photo(
                VIEW,
                prints=prints,
                spots=(spot,),
                glares=(Glare(60, 120, 4, 5.0),),
                colour=colour,
                paper=0.5,
                camera=PHONE,
            ),
            7,
        )
        spots, _ = detect_spots(img, colour="auto", luma=True)
        assert len(spots) == 1 and spots[0].evidence.colour == colour
        assert np.hypot(spots[0].u - 170.4, spots[0].v - 130.3) < 0.3


def test_red_ink_clipped_on_bright_paper_beside_a_dim_spot_is_not_a_second_spot():
    # The benchmark's one miss at 0.3x (photo 64, speckle 0.2): bright paper clips red ink's red, and
    # the ink's box reaches the dim spot 35 px away; the luma centroid ran off the ink to the spot's
    # light and a fit beside it made a second "spot" 23 px from the ink. A centre must lie on its blob.
    view = look_down((320, 240), 0.3, centre=(450.0, 0.0))
    truth = (125.0757, 118.2472)
    spot = LaserSpot(*truth, 1.8865, 0.2510, speckle=0.2, aspect=0.8365, angle_deg=47.88)
    cross_at, ink_at = view.unproject(np.array([[112.69, 155.43], [94.56, 95.89]]))
    photo = Photo(
        view,
        prints=(cross_print(cross_at, 10), ink_dot(ink_at, 2.857)),
        spots=(spot,),
        paper=0.4331,
        tint=(0.9674, 0.9372, 1.0),
        gradient=0.0481,
        vignetting=0.1423,
        camera=PhoneCamera(jpeg=86),
    )
    img = render(photo, 64)
    spots, _ = detect_spots(img, colour="auto", luma=True, expect=None)
    assert len(spots) == 1 and spots[0].evidence.colour == "red"
    assert np.hypot(spots[0].u - truth[0], spots[0].v - truth[1]) < 0.3
    assert "not brighter than the paper" in no_spot(render(replace(photo, spots=()), 64))


def test_exposure_advice_for_clipped_faint_and_good_spots():
    big = detect_spots(photo("red", 30.0, 1, sigma=3.0, tilt=0)[1], colour="auto", luma=True)[0]
    adv = exposure_advice(big)
    assert adv.clipped_px > 40 and adv.stops <= -1
    assert adv.advice.startswith(f"spot clipped over {adv.clipped_px} px: lower the exposure by about")
    assert adv.advice.endswith("or turn on the laser-off reference")
    assert "reference" not in exposure_advice(big, reference=True).advice
    faint = detect_spots(photo("green", 0.2, 1, sigma=3.0, tilt=30, paper=0.6)[1], colour="auto", luma=True)[
        0
    ]
    adv = exposure_advice(faint)
    assert adv.clipped_px == 0 and adv.contrast < 0.2 and adv.advice.startswith("spot faint")
    good = detect_spots(photo("red", 1.0, 1, sigma=1.5, tilt=0)[1], colour="auto", luma=True)[0]
    adv = exposure_advice(good)
    assert adv.advice is None and adv.stops == 0 and adv.clipped_px <= 40


def test_bad_photos_give_one_line_each_and_the_batch_goes_on(tmp_path):
    (u, v), good = photo("red", 3.0, 2)
    for name, img in {
        "good.jpg": good,
        "tiny.png": np.full((1, 1, 3), 128, np.uint8),
        "black.png": np.zeros((160, 200, 3), np.uint8),
        "white.png": np.full((160, 200, 3), 255, np.uint8),
    }.items():
        cv2.imwrite(str(tmp_path / name), img)
    (tmp_path / "notes.jpg").write_text("not an image\n")
    names = ["notes.jpg", "tiny.png", "black.png", "white.png", "good.jpg", "missing.jpg"]
    res = measure_batch([tmp_path / n for n in names], Options())
    assert [r.name for r in res] == [str(tmp_path / n) for n in names]
    why = {n: r.error for n, r in zip(names, res)}
    assert "not an image OpenCV can decode" in why["notes.jpg"]
    assert "1x1 px, too small" in why["tiny.png"]
    assert "black" in why["black.png"] and "white, clipped everywhere" in why["white.png"]
    assert "no such file" in why["missing.jpg"] and why["good.jpg"] is None
    assert all("\n" not in e and r.warnings == [e] and not r.spots for r, e in zip(res, why.values()) if e)
    ok = res[names.index("good.jpg")]
    assert ok.colour == "red" and len(ok.spots) == 1 and np.hypot(ok.spots[0].u - u, ok.spots[0].v - v) < 0.3
    cam = Camera((640, 480), np.array([[500.0, 0, 319.5], [0, 500, 239.5], [0, 0, 1]]), np.zeros(5))
    wrong = measure_batch([tmp_path / "good.jpg"], Options(), camera=cam)[0]
    assert "image is 200x160 px but the camera was calibrated at 640x480 px" in wrong.error


def test_results_say_why_in_json():
    spots, _ = detect_spots(photo("green", 10.0, 3)[1], colour="auto", luma=True)
    d = spots[0].to_dict()["evidence"]
    assert d["colour"] == "green" and d["clipped_px"] > 0 and d["rim_shift"] >= SHIFT_MIN
    assert d["rule"] == "rim" and d["cut"] is False
    assert set(d) >= {"confidence", "excess", "light", "rim_shift", "flux", "clipped_fraction", "white_px"}
