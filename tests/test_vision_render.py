"""The synthetic renderer's own truth: geometry in mm and px, sub-pixel edges and spots."""

import numpy as np
import pytest

from lasercal.vision.render import (
    FULL,
    LaserSpot,
    Photo,
    Print,
    _speckle,
    aruco_print,
    look_down,
    render,
    square_corners,
)


def test_look_down_scale_orientation_and_round_trip():
    v = look_down((800, 600), 0.3, centre=(450.0, 20.0), dist=(-0.1, 0.02, 0, 0, 0), z=-8)
    c = v.project([[450.0, 20.0], [460.0, 20.0], [450.0, 30.0]])
    assert c[0] == pytest.approx([399.5, 299.5])
    assert c[1] - c[0] == pytest.approx([10 / 0.3, 0], abs=0.05)  # +x is the photo's right
    assert c[2] - c[0] == pytest.approx([0, -10 / 0.3], abs=0.05)  # +y is the photo's up
    xy = np.random.default_rng(0).uniform([340, -60], [560, 100], (40, 2))
    assert np.allclose(v.unproject(v.project(xy)), xy, atol=1e-6)


def test_square_corners_follow_opencv_order_clockwise_from_above():
    c = square_corners((10, 20), 4)
    assert c.tolist() == [[8, 22], [12, 22], [12, 18], [8, 18]]
    r = square_corners((0, 0), 2, 90)
    assert np.allclose(r[0], [-1, -1])  # top-left turned a quarter counter-clockwise


def test_print_edges_land_at_exact_subpixel_places():
    v = look_down((200, 150), 0.3, centre=(0.0, 0.0))
    left = 4.37  # mm: a black half-plane x > left, seen through no blur
    item = Print(np.zeros((1, 1), np.float32), np.array([[left, 20], [40, 20], [40, -20], [left, -20]]))
    img = render(Photo(v, (item,), paper=0.8, read_noise=0, shot_noise=0, psf=0), 0)[..., 2].astype(float)
    row = img[75, 90:170] / img[75, 5]  # 1 on paper, 0 on the black part
    edge_px = 90 - 0.5 + row.sum()  # paper coverage of the row, in pixels
    assert edge_px == pytest.approx(v.project([[left, 0]])[0, 0], abs=0.03)


def test_marker_print_matches_opencv_marker_image():
    v = look_down((300, 300), 0.25, centre=(0.0, 0.0))
    img = render(
        Photo(
            v,
            (aruco_print("DICT_4X4_50", 7, square_corners((0, 0), 60)),),
            read_noise=0,
            shot_noise=0,
            paper=1.0,
            tint=(1, 1, 1),
        ),
        0,
    )
    # The 6x6 cells of 10 mm sit 40 px apart: sample each cell's centre.
    centres = v.project([[-25 + 10 * j, 25 - 10 * i] for i in range(6) for j in range(6)])
    cells = (
        img[np.round(centres[:, 1]).astype(int), np.round(centres[:, 0]).astype(int), 0].reshape(6, 6) > 128
    )
    import cv2

    ref = cv2.aruco.generateImageMarker(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), 7, 6) > 128
    assert (cells == ref).all()


def test_noise_free_spot_centroid_is_the_truth():
    v = look_down((100, 100), 0.3)
    u0, v0 = 47.31, 52.77
    img = render(
        Photo(
            v,
            spots=(LaserSpot(u0, v0, 2.3, 0.5, aspect=0.6, angle_deg=25),),
            read_noise=0,
            shot_noise=0,
            paper=0.3,
        ),
        0,
    )[..., 2].astype(float)
    w = img - np.median(img)
    yy, xx = np.mgrid[:100, :100]
    assert (w * xx).sum() / w.sum() == pytest.approx(u0, abs=0.01)  # 8-bit rounding only
    assert (w * yy).sum() / w.sum() == pytest.approx(v0, abs=0.01)


def test_saturation_bloom_and_jpeg():
    v = look_down((100, 100), 0.3)
    spot = (LaserSpot(50, 50, 2.0, 5.0),)
    plain = render(Photo(v, spots=spot, paper=0.5), 0)
    bloom = render(Photo(v, spots=spot, paper=0.5, bloom=0.5), 0)
    assert plain[..., 2].max() == FULL and (bloom[..., 2] == FULL).sum() > (plain[..., 2] == FULL).sum()
    jpeg = render(Photo(v, spots=spot, paper=0.5, jpeg=70), 0)
    assert (
        jpeg.dtype == np.uint8 and jpeg.shape == (100, 100, 3) and np.abs(jpeg.astype(int) - plain).max() > 3
    )


@pytest.mark.parametrize("contrast", [0.2, 0.6, 1.0])
def test_speckle_contrast_and_mean(contrast):
    s = _speckle((400, 400), 1.5, contrast, np.random.default_rng(1))
    assert s.mean() == pytest.approx(1, abs=1e-3) and s.std() == pytest.approx(contrast, rel=0.1)
    assert s.min() >= 0
