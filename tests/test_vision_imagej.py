"""The ImageJ emulation: thresholds, Centroid / Center of Mass, the +0.5 px convention."""

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError
from lasercal.vision.imagej import default_threshold, gray8, measure, otsu_threshold
from lasercal.vision.render import LaserSpot, Photo, look_down, marker_prints, marker_sheet, render

VIEW = look_down((320, 240), 0.3, centre=(450.0, 0.0))


def test_default_threshold_splits_two_levels_midway_and_ignores_0_and_255():
    hist = np.zeros(256, int)
    hist[60], hist[180] = 500, 400
    t = default_threshold(hist)
    assert 60 <= t < 180 and abs(t - 120) <= 1
    hist[0], hist[255] = 10**6, 10**6  # erased and clipped areas must not move it
    assert default_threshold(hist) == t


def test_default_threshold_caps_a_dominant_mode():
    # Paper (mode at 150) dwarfs a small bright spot: without the cap the level hugs the paper.
    hist = np.zeros(256, int)
    hist[145:156] = [10, 30, 80, 300, 2000, 90000, 2000, 300, 80, 30, 10]
    hist[230:250] = 20
    t = default_threshold(hist)
    assert 150 < t < 230


def test_default_threshold_of_a_flat_histogram_is_128():
    hist = np.zeros(256, int)
    hist[100] = 50
    assert default_threshold(hist) == 128


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_otsu_matches_opencv(seed):
    rng = np.random.default_rng(seed)
    img = np.concatenate(
        [rng.normal(rng.uniform(30, 120), 12, 3000), rng.normal(rng.uniform(140, 230), 15, 1000)]
    )
    img = np.clip(img, 0, 255).astype(np.uint8).reshape(40, 100)
    t_cv, _ = cv2.threshold(img, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    assert otsu_threshold(np.bincount(img.ravel(), minlength=256)) == int(t_cv)


def test_gray8_is_the_unweighted_mean():
    img = np.array([[[10, 20, 31], [255, 0, 0]]], np.uint8)
    assert gray8(img).tolist() == [[20, 85]]


def test_centroid_and_center_of_mass_of_a_disc():
    img = np.full((60, 60, 3), 40, np.uint8)
    yy, xx = np.mgrid[:60, :60]
    disc = (xx - 30.0) ** 2 + (yy - 25.0) ** 2 <= 36
    img[disc] = 220
    img[25, 33] = 250  # a brighter pixel pulls Center of Mass, not Centroid
    c = measure(img, (0, 0, 60, 60), "centroid", "otsu")
    m = measure(img, (0, 0, 60, 60), "com", "default")
    assert (c.u, c.v) == pytest.approx((30.0, 25.0))
    assert m.u > 30.0 and m.v == pytest.approx(25.0)
    assert c.area == disc.sum() and c.sigma_u is None
    assert c.to_dict("imagej")["u"] == pytest.approx(30.5)


def test_otsu_in_a_drawn_box_reaches_a_few_tenths_of_a_pixel():
    rng = np.random.default_rng(0)
    err = []
    for i in range(15):
        u, v = rng.uniform(140, 180), rng.uniform(100, 140)
        img = render(Photo(VIEW, spots=(LaserSpot(u, v, 2.0, 0.4),), paper=0.5), i)
        ox, oy = rng.integers(-8, 9, 2)
        s = measure(
            img, (int(u) - 32 + ox, int(v) - 32 + oy, int(u) + 32 + ox, int(v) + 32 + oy), "com", "otsu"
        )
        err.append(np.hypot(s.u - u, s.v - v))
    assert 0.02 < np.sqrt(np.mean(np.square(err))) < 0.3


def test_default_threshold_fails_on_a_small_unsaturated_spot():
    img = render(Photo(VIEW, spots=(LaserSpot(160.3, 120.6, 2.0, 0.4),), paper=0.5), 0)
    with pytest.raises(VisionError, match="does not isolate the spot"):
        measure(img, (128, 88, 192, 152), "centroid", "default")


def test_whole_photo_with_markers_fails_outright():
    markers = marker_sheet(look_down((640, 480), 0.3, centre=(450.0, 0.0)), side=30)
    view = look_down((640, 480), 0.3, centre=(450.0, 0.0))
    img = render(Photo(view, marker_prints(markers), (LaserSpot(320.2, 240.7, 2.0, 3.0),), paper=0.5), 0)
    for thr in ("default", "otsu"):
        with pytest.raises(VisionError):
            measure(img, (0, 0, 640, 480), "centroid", thr)


def test_imagej_method_through_detect_spots():
    img = render(Photo(VIEW, spots=(LaserSpot(150.3, 110.8, 2.5, 3.0),), paper=0.5), 1)
    spots, warnings = detect_spots(img, method="imagej", imagej_mode="centroid", imagej_threshold="otsu")
    assert len(spots) == 1 and not warnings
    assert np.hypot(spots[0].u - 150.3, spots[0].v - 110.8) < 0.3 and spots[0].sigma_u is None
