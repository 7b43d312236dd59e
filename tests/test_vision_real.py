"""Issue 22: laser spots in real photographs (hand-labelled, ../shared/data/real-photos): every
labelled spot found, no spot invented, no photo lost to an internal fault; huge and odd-shaped
photos end in a measurement or one clean line."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from lasercal.vision.detect import detect_spots, measure_candidates, select
from lasercal.vision.errors import NoSpotError, VisionError
from lasercal.vision.images import exif_orientation, read_image, upright, upright_points
from lasercal.vision.measure import Options, measure_file, measure_photo
from lasercal.vision.overlay import draw

PHOTOS = Path(
    os.environ.get(
        "LASERCAL_REAL_PHOTOS", Path(__file__).resolve().parents[2] / "shared" / "data" / "real-photos"
    )
)
LABELS = json.loads((PHOTOS / "labels.json").read_text()) if (PHOTOS / "labels.json").is_file() else []
needs_photos = pytest.mark.skipif(not LABELS, reason=f"real photos not found in {PHOTOS}")


def tolerance(label: dict) -> float:
    """How far a found spot may lie from its label, px: max(4, 2 x the label's uncertainty)."""
    return max(4.0, 2.0 * label["uncertainty_px"])


@pytest.fixture(scope="module")
def measured():
    """The labelled photos' candidates, measured once as ``lasercal spots`` measures them, and rendered
    ones: the renderer's, lit papers and the scenes of issue 47's outside check."""
    from lasercal.vision import fit

    return fit.measure_labelled(PHOTOS), fit.rendered(40) + fit.lit_papers(60) + fit.wild(4)


def label(name):
    return next(e for e in LABELS if e["file"] == name)


@needs_photos
@pytest.mark.parametrize(
    "name", ["LiamAG+CLS-Beam-Monitor/laser4.png", "YuxueYang1204+Laser-Dot-Detector/2.jpg"]
)
def test_the_fit_harness_reports_what_the_command_reports(name):
    # Issue 47 item 1: the harness measured with every colour rule off and then decided, the command
    # decided while it measured; on laser4.png they reported spots 8 px apart (37.7 and 29.7 px from the
    # label). Now both measure through the physical gates and decide by one function (detect.select).
    from lasercal.vision import fit
    from lasercal.vision.decide import RULE

    harness = fit.photo_spots(fit.measure_labelled(PHOTOS, [label(name)])[0], RULE)
    command = measure_file(PHOTOS / name, Options(expect=None)).spots
    assert sorted((s.u, s.v) for s in harness) == sorted((s.u, s.v) for s in command)
    assert command  # a spot to compare


@needs_photos
def test_leave_one_source_out_finds_the_spots_and_invents_few(measured):
    # Issue 30: the rule is fitted without the source it is scored on, as on cameras never seen.
    # With this test's training set (40 phone renders, 60 lit papers, 4 of each issue-47 scene):
    # 19 of 21 found, 1 false, no photo lost; the bounds leave one photo's margin either way (a fold's
    # thresholds are the middle of equally good grid values: a tie moved by rounding can move a photo).
    # Issue 55's bar is scored by bench_vision_loso.py with the full training set (120 phone renders, 8 of
    # each issue-47 scene, the issue-55 kinds: ~3x this test's CPU): 20 of 21, 0 false, median 0.50 px.
    from lasercal.vision import fit

    real, synth = measured
    folds = fit.leave_one_source_out(real, synth)
    assert set(folds) == {p.source for p in real} and len(folds) == 7
    total = sum((s for _, s in folds.values()), fit.Score())
    assert total.labelled == 21 and total.photos == 24
    assert total.found >= 18 and total.false <= 2 and total.unmeasurable == 0, total
    assert total.median <= 0.6, total
    # Issue 47 item 3: each fold's rule, fitted without one source, takes no white light for a laser (the
    # bluish torch, the cool lamp and the white glare of the rim-shift test below, on every paper).
    white = []
    for k, paper in enumerate(PAPERS.values()):
        p = np.array(paper)
        for amp in (3.0, 30.0):
            for light in (
                amp * p * np.array([1.3, 1.0, 0.8]),
                amp * p * np.array([1.6, 1.1, 0.7]),
                amp * p.max(),
            ):
                img = lit_paper(p, light * np.ones(3), k)[1]
                white.append(measure_candidates(img, "auto", None, 2.2, True))
    for rule, _ in folds.values():
        taken = [len(select_or_none(tries, rule)) for tries in white]
        assert sum(taken) == 0, (rule, taken)
    # In-sample can only be as good or better: the protocol is what stands for unseen cameras.
    everything = fit.fit_rule(real + synth)
    assert fit.score(real, everything).errors <= total.errors


def select_or_none(tries, rule):
    """The spots ``lasercal spots --expect any`` reports from measured candidates under ``rule``."""
    try:
        return select(tries, "x", None, rule)[1]
    except NoSpotError:
        return []


@needs_photos
def test_white_flashlight_gives_no_spot():
    # A clipped white hotspot without a laser-coloured fringe is no spot, whatever is expected.
    entry = next(e for e in LABELS if e["file"].endswith("flashlight.jpg"))
    res = measure_file(PHOTOS / entry["file"], Options(expect=None))
    assert res.error is not None and "no red or green laser spot found" in res.error


@needs_photos
def test_exif_orientation_is_read_and_ignored_for_coordinates():
    # The flashlight photo is flagged as rotated (EXIF 8): pixels stay in the stored grid.
    entry = next(e for e in LABELS if e["exif_orientation"] not in (None, 1))
    path = PHOTOS / entry["file"]
    assert read_image(path).shape[:2] == (entry["height"], entry["width"])
    assert exif_orientation(path) == entry["exif_orientation"]


@pytest.mark.parametrize("orientation", range(1, 9))
def test_upright_turns_pixels_and_points_alike(orientation, tmp_path):
    img = np.zeros((30, 50, 3), np.uint8)
    img[7, 41] = 255  # one lit pixel at (u, v) = (41, 7) in the stored grid
    shown = upright(img, orientation)
    (x, y) = upright_points([[41, 7]], img.shape, orientation)[0]
    assert shown[int(y), int(x)].max() == 255 and shown.sum() == img.sum()
    # Pillow writes the tag as a camera does; cv2 (IMREAD_IGNORE_ORIENTATION) keeps the stored grid.
    from PIL import Image

    path = tmp_path / "o.jpg"
    exif = Image.Exif()
    exif[274] = orientation
    Image.fromarray(img[..., ::-1]).save(path, exif=exif)
    assert exif_orientation(path) == orientation and read_image(path).shape == img.shape
    up = draw(img, [], orientation=orientation)
    assert up.shape == shown.shape


def paper_with_spot(shape, rng):
    """A grey-beige photo of ``shape`` with one clipped red spot (white core, pink rim) at a known place."""
    h, w = shape
    img = np.empty((h, w, 3), np.uint8)
    img[:] = (150, 165, 180)  # BGR, beige paper
    u, v = 0.37 * w + 0.3, 0.61 * h + 0.7
    y0, x0 = max(int(v) - 40, 0), max(int(u) - 40, 0)
    yy, xx = np.mgrid[y0 : min(int(v) + 40, h), x0 : min(int(u) + 40, w)]
    g = np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * 4.0**2))
    lin = ((img[y0 : y0 + g.shape[0], x0 : x0 + g.shape[1]] / 255.0) ** 2.2).astype(float)
    lin[..., 2] += 30 * g  # a red laser 30x over clipping: white core by blooming, pink rim
    lin[..., :2] += 1.5 * g[..., None]
    img[y0 : y0 + g.shape[0], x0 : x0 + g.shape[1]] = np.clip(255 * np.clip(lin, 0, 1) ** (1 / 2.2), 0, 255)
    noise = rng.integers(-2, 3, (min(h, 256), min(w, 256), 3))
    img[: noise.shape[0], : noise.shape[1]] = np.clip(img[: noise.shape[0], : noise.shape[1]] + noise, 0, 255)
    return (u, v), img


def test_a_50_megapixel_photo_is_measured():
    (u, v), img = paper_with_spot((6000, 8500), np.random.default_rng(1))
    res = measure_photo(img, "big.png", Options())
    assert len(res.spots) == 1 and np.hypot(res.spots[0].u - u, res.spots[0].v - v) < 1.0


@pytest.mark.parametrize("shape", [(1, 10_000), (10_000, 1), (16, 10_000), (40, 40_000)])
def test_strips_are_measured_or_refused_in_one_line(shape):
    (u, v), img = paper_with_spot(shape, np.random.default_rng(2))
    try:
        res = measure_photo(img, "strip.png", Options())
    except VisionError as exc:
        msg = str(exc)
        assert msg.startswith("strip.png: ") and "\n" not in msg and "could not be measured" not in msg
    else:  # a strip too narrow for the spot cuts it: then its centre is extrapolated, and flagged
        s = res.spots[0]
        assert len(res.spots) == 1 and np.hypot(s.u - u, s.v - v) < (4.0 if s.evidence.cut else 1.0)
        assert s.evidence.cut or min(shape) >= 40


def test_a_fault_inside_the_measurement_is_one_line_naming_photo_and_stage(tmp_path, monkeypatch):
    from lasercal.vision import measure

    def broken(*args, **kwargs):
        raise cv2.error("OpenCV(5.0.0) imgwarp.cpp:1427: error: (-215:Assertion failed) dst.cols < SHRT_MAX")

    cv2.imwrite(str(tmp_path / "p.png"), paper_with_spot((120, 160), np.random.default_rng(3))[1])
    monkeypatch.setattr(measure, "detect_spots", broken)
    res = measure_file(tmp_path / "p.png")
    assert res.error.startswith(f"{tmp_path / 'p.png'}: could not be measured: internal error while finding")
    assert "dst.cols < SHRT_MAX" in res.error and "\n" not in res.error and not res.spots


PAPERS = {  # BGR, linear reflectance x light: the surfaces of the photos
    "white": (0.80, 0.80, 0.80),
    "yellow": (0.25, 0.65, 0.75),
    "beige": (0.45, 0.55, 0.65),
    "grey": (0.30, 0.30, 0.30),
    "cardboard": (0.18, 0.30, 0.45),
    "blue": (0.55, 0.30, 0.15),
}


def lit_paper(paper, light, seed):
    """A 4:2:0 JPEG of paper (linear BGR) with ``light`` (BGR, linear, at the peak) added in a
    Gaussian spot of sigma 4 px at a known place, clipped and gamma-encoded as a camera does."""
    rng = np.random.default_rng(seed)
    u, v = 101.3 + rng.uniform(-5, 5), 77.6 + rng.uniform(-5, 5)
    yy, xx = np.mgrid[:160, :200]
    g = np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / 32.0)[..., None]
    lin = np.array(paper) * (1 + 0.01 * rng.standard_normal((160, 200, 3))) + g * np.array(light)
    img = np.clip(255 * np.clip(lin, 0, 1) ** (1 / 2.2), 0, 255).astype(np.uint8)
    return (u, v), cv2.imdecode(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1], 1)


@pytest.mark.parametrize("paper", PAPERS)
def test_rim_shift_tells_laser_light_from_white_light_on_any_paper(paper):
    p = np.array(PAPERS[paper])
    for seed, amp in enumerate((3.0, 30.0)):  # the spot's peak light over the paper's
        # A red laser (its light leaks a little into green and blue) is found, by its rim.
        (u, v), img = lit_paper(p, amp * p.max() * np.array([0.03, 0.06, 1.0]), seed)
        spots, _ = detect_spots(img, colour="auto", luma=True)
        assert len(spots) == 1 and np.hypot(spots[0].u - u, spots[0].v - v) < 0.5
        assert spots[0].evidence.rule == "rim" and spots[0].evidence.colour == "red"
        # Light off the white balance on the same paper (diffuse, so in the paper's colour): a
        # bluish torch, a warm lamp (red 1.5x green, 2.5x blue), a cool lamp; and a specular white
        # glare and a warm one: none of these is a red or a green laser.
        tints = ([1.3, 1.0, 0.8], [0.6, 1.0, 1.5], [1.6, 1.1, 0.7])
        lights = [amp * p * np.array(t) for t in tints]
        lights += [amp * p.max() * np.ones(3), amp * p.max() * np.array([0.6, 1.0, 1.5])]
        for k, light in enumerate(lights):
            warm = k in (1, 4)
            try:
                spots, warnings = detect_spots(
                    lit_paper(p, light, seed)[1], colour="auto", luma=True, expect=None
                )
            except NoSpotError:
                continue
            # Issue 30: a clipped white core with a warm fringe is taken for an overexposed laser
            # spot (rule "core"); a warm lamp or glare can look like that (rim shift 1.8-2.0 on
            # yellow and cardboard). It is then reported as unlikely, with the advice to lower the
            # exposure or take a laser-off photo. White, bluish and cool light never passes. Issue 55: on
            # white paper (neutral) a warm lamp's white core alone in the photo is what a colourless laser
            # core looks like, and rule "bare" reads it, as unlikely and with the same advice.
            unlikely = all(s.evidence.rule in ("core", "bare") and s.evidence.confidence < 0.5 for s in spots)
            assert warm and unlikely
            assert any("--reference" in w for w in warnings)
