"""Laser-spot detection and the precise sub-pixel centroid.

Coordinates are pixels in OpenCV's convention (pixel centres at integer coordinates, ``u`` to the
right, ``v`` down); intensities are digital numbers (DN) of the photo. ImageJ reports the same
point at ``(u + 0.5, v + 0.5)``.

The pipeline, one module a stage: :mod:`vision.candidates` (where a spot may be),
:mod:`vision.features` (what each candidate looks like), :mod:`vision.decide` (whether it is laser
light) and :mod:`vision.refine` (its sub-pixel centre). This module runs them over a photo.

Detection, of a red (or green) laser on paper, cardboard or a wall as real cameras record it:
from a dim coloured spot to a white clipped core whose colour survives only in a red, orange,
pink (or pale green) rim, and spots hundreds of pixels wide.

1. candidates: on a 1/f-size block average (fast on 12-megapixel photos), the paper level (a
   tile percentile, so black markers do not sink it) is removed from the laser's channel and
   from its *colour excess* (the channel minus the brighter other one: ~0 on white paper, black
   ink and white glare alike). A region brighter than the paper in the laser's channel is a
   candidate as a whole when a few of its pixels are laser-coloured (the halo of a white core).
   The same on a coarse copy (~64 rows) finds spots too wide for the tiles, and clipped white
   blobs are candidates too (the cores of spots far past clipping).
2. each candidate, with a plane fitted to the box border as the local background (a box over
   :data:`MEASURE_SIDE` px on a shrunk copy), is measured (:class:`Evidence`) and rejected when
   it is not brighter than the paper in the laser's channel *and* in the luma (red ink: a
   phone's colour correction lifts its red above the paper's, but it takes light away), when
   its rim does not shift towards the laser's hue relative to the paper (white light of any
   kind, see :func:`_rim_shift`), when it is smaller than any lens-blurred spot, not a compact
   ellipse, or a JPEG fringe beside ink (weak, next to darker pixels, or dark at its centre).
   The spots left are ranked by the light they add (:attr:`Evidence.strength`).
3. centroid (``precise``): an elliptical profile fitted in linear light to the spot and its
   flanks; clipped pixels only bound the profile from below, so the centre of a clipped spot
   comes from the plateau's edge and the unclipped flanks (see :func:`_fit_profile`). In a
   4:2:0 JPEG an unclipped spot is fitted in the luma plus a fifth of the chroma difference Cr
   (see :data:`CHROMA_WEIGHT`). Its sigma is the fit's gain through the pixels' error
   covariance, estimated from the odd part of its residuals (see :func:`_centre_sigma`). Where
   printed ink lies under a spot, its pixels are left out; spots on ink are flagged.

With a laser-off reference photo the candidates come from the difference image, which holds
nothing but laser light, and fainter spots are believed. ``colour="auto"`` tries both lasers
and keeps the more convincing.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from lasercal.vision.bare import RIM_MAX_PX, RIM_MIN_PX, RIM_STRAY, counted, lopsided, rim_centre, white_cores
from lasercal.vision.candidates import Candidate, _octave, _shrink, find_candidates
from lasercal.vision.decide import (
    CLOSE,
    MEASURE_SIDE,
    REASONS,
    RULE,
    SHIFT_MIN,
    DecisionRule,
    Rejection,
    _dedupe,
    _dominant,
    _keep_strongest,
    _strength,
    finish,
    judge,
    measure_spot,
    refusal,
)
from lasercal.vision.errors import NoSpotError, VisionError
from lasercal.vision.features import CLIP, LUMA_CLIP
from lasercal.vision.imagej import measure as imagej_measure
from lasercal.vision.images import all_at_least, full_scale
from lasercal.vision.ring import RING_MIN
from lasercal.vision.spot import CHANNEL, Evidence, Pending, Spot

__all__ = [
    "CLOSE",
    "REASONS",
    "RULE",
    "SHIFT_MIN",
    "Candidate",
    "DecisionRule",
    "Evidence",
    "Rejection",
    "Spot",
    "detect_spots",
    "find_candidates",
    "judge",
    "measure_candidates",
    "measure_spot",
    "select",
]


def detect_spots(
    img: np.ndarray,
    name: str = "image",
    colour: str = "red",
    reference: np.ndarray | None = None,
    expect: int | None = 1,
    method: str = "precise",
    imagej_mode: str = "centroid",
    imagej_threshold: str = "default",
    imagej_box: int = 64,
    gamma: float = 2.2,
    luma: bool = False,
    search: np.ndarray | None = None,
    predicted: tuple[float, float, float] | None = None,
    rule: DecisionRule = RULE,
) -> tuple[list[Spot], list[str]]:
    """Find and measure the laser spots of one photo.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16
    name : str, the photo's name for messages
    colour : "red", "green" or "auto" (try both; the colour taken is each spot's ``evidence.colour``)
    reference : laser-off photo of the same view and size, or None
    expect : int or None, the number of spots expected; None accepts any number
    method : "precise" or "imagej"
    imagej_mode, imagej_threshold, imagej_box : see :func:`vision.imagej.measure`
    gamma : float, the photo's encoding gamma (2.2 camera JPEG, 1 linear)
    luma : bool, precise centroid on the luma (for JPEGs with subsampled chroma)
    search : (n, 2) array or None, px: a polygon (the sheet, when its markers are found) outside
        which no spot is sought
    predicted : (u, v, sigma) px or None: where the spot should be (validate knows it within the
        model's uncertainty); candidates are ranked by their strength times the prior's density
    rule : DecisionRule, the decision's parameters (see :mod:`vision.decide`)

    Returns
    -------
    spots : list of Spot, sorted by v then u
    warnings : list of str

    Raises
    ------
    NoSpotError
        Nothing that looks like laser light.
    SpotCountError
        More spots than ``expect``, close in evidence.
    """
    if reference is not None and reference.shape != img.shape:
        raise VisionError(
            f"{name}: the reference photo is {reference.shape[1]}x{reference.shape[0]} px, "
            f"the photo {img.shape[1]}x{img.shape[0]} px"
        )
    if colour != "auto" and colour not in CHANNEL:
        raise VisionError(f"unknown laser colour '{colour}' (red, green or auto)")
    tries = measure_candidates(img, colour, reference, gamma, luma, search)
    colour, spots, warnings = select(tries, name, expect, rule, predicted, img)
    if method == "imagej":
        measured = []
        for s in spots:
            box = _imagej_box(img.shape, s, imagej_box)
            try:
                measured.append(imagej_measure(img, box, imagej_mode, imagej_threshold, colour))
            except VisionError as exc:
                warnings.append(f"imagej: spot at ({s.u:.1f}, {s.v:.1f}) px: {exc}")
        if not measured:
            raise NoSpotError(f"{name}: the imagej method measured none of the {len(spots)} spots found")
        spots = measured
    elif method != "precise":
        raise VisionError(f"unknown centroid method '{method}' (precise or imagej)")
    return sorted(spots, key=lambda s: (round(s.v), s.u)), warnings


def measure_candidates(
    img: np.ndarray,
    colour: str = "auto",
    reference: np.ndarray | None = None,
    gamma: float = 2.2,
    luma: bool = False,
    search: np.ndarray | None = None,
) -> dict[str, tuple[list[Spot], list[Rejection]]]:
    """Stages 1, 2 and 4 for each laser colour tried: the candidates measured, through the physical
    gates only (light, size, shape, fringes: :func:`~vision.decide.measure_spot`). Whether each is laser
    light by its colour (stage 3) is :func:`select`'s to judge, with any :class:`DecisionRule`: the
    command and the benchmark that fits the rule (:mod:`vision.fit`) measure a photo the same way.

    Parameters
    ----------
    img, colour, reference, gamma, luma, search : as for :func:`detect_spots`

    Returns
    -------
    dict colour -> (spots, rejected): the candidates that pass the physical gates (not yet judged nor
    deduplicated), and those refused
    """
    if img.ndim == 2:
        colours = ["red"]  # one channel: colour is moot
    else:
        colours = list(CHANNEL) if colour == "auto" else [colour]
    shrunk: dict[int, np.ndarray] = {}  # one photo, two colours: shrink it once
    return {c: _find(img, c, reference, gamma, luma, shrunk, search) for c in colours}


def select(
    tries: dict[str, tuple[list[Spot], list[Rejection]]],
    name: str,
    expect: int | None,
    rule: DecisionRule = RULE,
    predicted: tuple[float, float, float] | None = None,
    img: np.ndarray | None = None,
) -> tuple[str, list[Spot], list[str]]:
    """The photo's spots from its measured candidates: judged by ``rule``, deduplicated, the laser's
    colour decided (the colour whose spots are the more convincing), ranked and counted.

    Parameters
    ----------
    tries : from :func:`measure_candidates`
    name, expect, predicted : as for :func:`detect_spots`
    rule : DecisionRule
    img : the photo or None, to name its white clipped blobs when no spot is found

    Returns
    -------
    colour : str, the laser colour measured
    spots : list of Spot
    warnings : list of str

    Raises
    ------
    NoSpotError, SpotCountError
        As :func:`detect_spots`.
    """
    judged = {c: _judged(spots, rejected, rule) for c, (spots, rejected) in tries.items()}

    def rank(s: Spot) -> float:
        return _strength(s) * _prior(s, predicted)

    warnings = []
    # The laser's colour is the one its rim shows most clearly (the margin over the rule): an LED or
    # a lit object of the other colour may well add more light.
    score = {c: max((rank(s) for s in spots), default=0.0) for c, (spots, _) in judged.items()}
    clear = {
        c: max((_colour_margin(s, rule) for s in spots), default=-np.inf) for c, (spots, _) in judged.items()
    }
    # Of the colours whose rims are about as clear as the clearest (within a factor of 2 in rim
    # shift: both capped, say), the one with the strongest spot.
    colour = max(score, key=lambda c: (clear[c] >= max(clear.values()) - np.log(2), score[c]))
    if score[colour] == 0:
        colour = " or ".join(judged) if len(judged) > 1 else colour
        rejected = [r for _, rej in judged.values() for r in rej]
        raise NoSpotError(f"{name}: no {colour} laser spot found{_why_none(rejected, img)}")
    spots = judged[colour][0]
    others = [c for c in judged if c != colour and judged[c][0]]
    if others:
        warnings.append(
            f"both red and green spots found: measured {colour} (strength {score[colour]:.3g} against "
            f"{score[others[0]]:.3g}); give --color to choose"
        )
    if img is not None and img.ndim == 2:
        warnings.append("grey photo: white reflections cannot be told from laser light")
    # Issue 55's choice among several, with any number of spots expected (--expect any): with a count
    # expected, the strongest are kept, and the others named with their strength.
    if len(spots) > 1 and expect is None:
        spots, note = _laser_like(spots, rule.adds_share, rule.dominance, rank, rule.lopsided_max)
        if note:
            warnings.append(note)
    if len(spots) > 1 and expect is None:
        spots, note = _point_symmetric(spots, rule.lopsided_max, rule.dominance, rank)
        if note:
            warnings.append(note)
    if expect is None:
        spots, note = _dominant(spots, rule.dominance, rank)
        if note:
            warnings.append(note)
    elif len(spots) > expect:
        spots, note = _keep_strongest(spots, expect, name, rank)
        warnings.append(note)
    for sp in spots:
        if sp.evidence is not None and sp.evidence.cut:
            warnings.append(
                f"spot at ({sp.u:.1f}, {sp.v:.1f}) px is cut by the photo's edge: its centre is extrapolated "
                "from the part in view, and its sigma does not count that"
            )
        if sp.on_ink:
            warnings.append(
                f"spot at ({sp.u:.1f}, {sp.v:.1f}) px lies on printed ink, which swallows part of its "
                "light: its centre may be off by a few tenths of a pixel (aim beside the mark)"
            )
        if sp.evidence is not None and sp.evidence.rule in ("core", "bare"):
            warnings.append(
                f"spot at ({sp.u:.1f}, {sp.v:.1f}) px is clipped white with only a faint laser-coloured "
                f"fringe (probability {sp.evidence.confidence:.2f}): lower the exposure, or take a "
                "laser-off photo (--reference)"
            )
    if expect is not None and len(spots) < expect:
        warnings.append(f"{len(spots)} spot{'s' * (len(spots) != 1)} found where {expect} are expected")
    return colour, spots, warnings


def _judged(
    spots: list[Spot], rejected: list[Rejection], rule: DecisionRule
) -> tuple[list[Spot], list[Rejection]]:
    """Spots judged by ``rule`` (those it refuses become rejections), given their precise centres
    (:func:`~vision.decide.finish`), deduplicated."""
    kept, refused = [], list(rejected)
    for s in spots:
        ev = s.evidence if s.evidence is None else judge(s.evidence, rule)
        if ev is not None and ev.rule is None:
            refused.append(Rejection(refusal(s.evidence, rule), s.u, s.v, ev))
            continue
        done = finish(replace(s, evidence=ev))
        if isinstance(done, Rejection):
            refused.append(done)
            continue
        # A ringed core that stands for a refused fit brings evidence of its own to judge; judging the
        # evidence just judged again would only copy it (judge reads neither rule nor confidence).
        if done.evidence is not ev:
            done = replace(done, evidence=judge(done.evidence, rule))
        kept.append(_rim_centred(done, rule.lean_min))
    # A colourless core is read only where no spot shows the laser's colour (see vision.bare).
    if any(s.evidence is None or s.evidence.rule != "bare" for s in kept):
        refused += [Rejection("white", s.u, s.v, s.evidence) for s in kept if s.evidence.rule == "bare"]
        kept = [s for s in kept if s.evidence is None or s.evidence.rule != "bare"]
    return _one_per_light(_dedupe(kept)), refused


def _rim_centred(s: Spot, lean_min: float) -> Spot:
    """A clipped spot centred on the rim of its saturation (:func:`vision.bare.rim_centre`) where its
    light is at least ``lean_min`` lopsided (:attr:`DecisionRule.lean_min`) and the precise fit strays
    from the rim by over :data:`~vision.bare.RIM_STRAY`: the fit weighs the clipped pixels and the
    flanks, and both lean towards whatever joins the core on one side (a flare streak, a glint); the
    round part of the rim does not. Where the light is point-symmetric, or the two agree, the fit is kept
    (it is the finer one: 0.02 px against the outline's quantisation, which a clip edge ragged by speckle
    and a 4:2:0 JPEG's blocky red make coarser). The sigma stays the fit's."""
    ev = s.evidence
    if ev is None or ev.rim_centre is None or ev.clipped_px <= 0 or (ev.lopsided or 0.0) < lean_min:
        return s
    u, v = ev.rim_centre
    if np.hypot(s.u - u, s.v - v) <= RIM_STRAY:
        return s
    return replace(s, u=float(u), v=float(v))


def _adds(s: Spot) -> float:
    """How much a spot's light is light added, not a surface's colour: its luma's rise over its laser
    channel's (:attr:`~vision.spot.Evidence.light` / :attr:`~vision.spot.Evidence.excess`). A laser adds
    light, and its cross-talk, blooming and clipping whiten its core: 0.7-1.5 on the shared photos and
    the renders. A red object (a box, a red-lit screen patch) is red because its other channels fall
    below the surface's: its luma barely rises, 0.3-0.45 on the renders."""
    ev = s.evidence
    return 1.0 if ev is None or ev.colour is None else float(ev.light / max(ev.excess, 1e-6))


def _laser_like(
    spots: list[Spot], share: float, dominance: float = 0.0, rank=_strength, most: float = RULE.lopsided_max
) -> tuple[list[Spot], str | None]:
    """Of several candidates, those that add light like the most laser-like one: their luma rise over
    their colour's (:func:`_adds`) at least ``share`` of its (:attr:`DecisionRule.adds_share`); and a
    warning naming the others. A bright red object outshines a small spot in flux, so strength alone
    chose it (issue 55). One far weaker is left to the dominance (:func:`_refused_among`). Only against a
    candidate whose clipping whitened its core (a white pixel): laser spots clipped in their own channel
    alone rise 0.46-0.62 in luma (three lasers in one photo, ``tests/test_vision_plane.py``), as far
    apart as a spot and a red object.

    The yardstick is none that :func:`_point_symmetric` refuses (over ``most``,
    :attr:`DecisionRule.lopsided_max`, while another candidate is under it): a lamp whose clipped white
    core an edge cuts adds more luma than a spot clipped in red alone, but it is no beam, and a spot is not
    refused for adding less than it (a rendered lamp at an edge refused the true spot so, 0.73 against
    0.99; :func:`_point_symmetric` then refuses the lamp)."""
    beams = [s for s in spots if _lopsided(s) <= most] or spots
    top = max(beams, key=_adds)
    if top.evidence is None or not top.evidence.white_px:
        return spots, None
    best = _adds(top)
    kept, rest = _refused_among(spots, lambda s: _adds(s) < share * best, dominance, rank)
    if not rest:
        return spots, None
    where = "; ".join(
        f"({s.u:.1f}, {s.v:.1f}) px (luma rise {_adds(s):.2f} of its colour's)" for s in rest[:3]
    )
    return kept, (
        f"several candidates: refused {len(rest)} that colour the photo more than they light it (a red "
        f"object, not a laser spot; the laser-like ones add {best:.2f}): {where}"
    )


def _refused_among(spots: list[Spot], bad, dominance: float, rank) -> tuple[list[Spot], list[Spot]]:
    """The candidates kept and those refused for ``bad`` (a predicate), when any is not bad: a bad one
    below ``dominance`` of the strongest good one's ``rank`` is kept, for the dominance
    (:func:`~vision.decide._dominant`) to name it for what it is, far weaker (a faint spot's noise
    makes it look lopsided, and its luma rises by a third of its red's)."""
    good = [s for s in spots if not bad(s)]
    if not good:
        return spots, []
    top = max(rank(s) for s in good)
    rest = [s for s in spots if bad(s) and rank(s) >= dominance * top]
    return [s for s in spots if s not in rest], rest


def _point_symmetric(
    spots: list[Spot], most: float, dominance: float = 0.0, rank=_strength
) -> tuple[list[Spot], str | None]:
    """Of several candidates, those whose light is point-symmetric about their centre as a beam's is
    (:attr:`~vision.spot.Evidence.lopsided` at most ``most``, :attr:`DecisionRule.lopsided_max`), when
    any is; and a warning naming the others. A glow along an edge lit red (the laser's scatter, an
    indicator) is laser light, clipped and compact, but the dark object cuts it on one side (issue 55).
    A spot the photo's edge cuts is not judged by it; one far weaker is left to the dominance
    (:func:`_refused_among`)."""

    kept, rest = _refused_among(spots, lambda s: _lopsided(s) > most, dominance, rank)
    if not rest:
        return spots, None
    where = "; ".join(f"({s.u:.1f}, {s.v:.1f}) px (lopsided {_lopsided(s):.2f})" for s in rest[:3])
    return kept, (
        f"several candidates: refused {len(rest)} whose light is cut on one side (a lit edge, not a "
        f"laser spot; a beam's light is point-symmetric about its centre, under {most:.2f}): {where}"
    )


def _lopsided(s: Spot) -> float:
    """How far a spot's light is from point-symmetric (:attr:`~vision.spot.Evidence.lopsided`); 0 for a
    spot the photo's edge cuts, whose light shows on one side whatever made it."""
    ev = s.evidence
    return 0.0 if ev is None or ev.cut or ev.lopsided is None else ev.lopsided


def _one_per_light(spots: list[Spot]) -> list[Spot]:
    """One spot for each light: of spots that lie within each other's laser-coloured light (its halo,
    :attr:`~vision.spot.Evidence.reach`), the strongest. A grey disc, a lighter patch or a glint in a
    spot's halo is lit by that spot: the same light, not a second spot (one that outshines the spot is
    lit on one side, and :attr:`DecisionRule.side_max` refuses it)."""

    out: list[Spot] = []
    for s in sorted(spots, key=_strength, reverse=True):
        if not any(np.hypot(s.u - o.u, s.v - o.v) <= max(_reach(s), _reach(o)) for o in out):
            out.append(s)
    return out


def _reach(s: Spot) -> float:
    """How far a spot's light reaches, px (its blob's radius at least)."""
    return max(0.0 if s.evidence is None else s.evidence.reach, np.sqrt(s.area / np.pi))


def _colour_margin(s: Spot, rule: DecisionRule) -> float:
    """How clearly a spot shows its laser's colour: its margin over its rule (0 for a spot in its own
    halo, rule "view", whose rim has no paper to compare with)."""
    ev = s.evidence
    if ev is None or ev.rule in ("view", "grey"):
        return 0.0
    if ev.rule == "ring":
        return float(np.log(ev.ring / RING_MIN))
    if ev.rule == "bare":
        return float(np.log(max(ev.rim_shift or 0.0, 1e-9) / rule.bare_shift))
    thr = rule.core_shift_min if ev.rule == "core" else rule.shift_min
    return float(np.log(max(ev.rim_shift or 0.0, 1e-9) / max(thr, 1e-9)))


def _prior(s: Spot, predicted: tuple[float, float, float] | None) -> float:
    """The density of the predicted position at a spot, relative to its peak (1 without a prediction);
    floored so that a strong spot far from a poor prediction can still win."""
    if predicted is None:
        return 1.0
    u, v, sigma = predicted
    d2 = ((s.u - u) ** 2 + (s.v - v) ** 2) / max(sigma, 1.0) ** 2
    return float(max(np.exp(-0.5 * d2), 1e-6))


def _why_none(rejected: list[Rejection], img: np.ndarray | None) -> str:
    """Why no spot was found: the rejections counted by reason, the best one's evidence, white blobs."""
    kinds = [k for k in REASONS if any(r.kind == k for r in rejected)]
    counts = ", ".join(f"{sum(r.kind == k for r in rejected)} {REASONS[k]}" for k in kinds)
    detail = f"; rejected: {counts}" if kinds else ""
    if rejected:  # the strongest candidate's evidence says how close it came
        best = max(rejected, key=lambda r: -1 if r.evidence is None else r.evidence.confidence)
        detail += f"; best candidate {best.describe()}"
    return detail + ("" if img is None else _white_blobs(img))


def _white_blobs(img: np.ndarray, min_px: int = 20) -> str:
    """A note on clipped white blobs, for a photo without a spot: a laser spot exposed far beyond
    clipping can lose the last of its colour and look like a reflection."""
    if img.ndim == 2:
        return ""
    white = all_at_least(img, LUMA_CLIP * full_scale(img)).astype(np.uint8)
    n, _, stats, cents = cv2.connectedComponentsWithStats(white, connectivity=8)
    big = [i for i in range(1, n) if stats[i, 4] >= min_px]
    if not big:
        return ""
    i = max(big, key=lambda i: stats[i, 4])
    return (
        f"; {len(big)} white clipped blob{'s' * (len(big) > 1)} without laser colour, the largest "
        f"{stats[i, 4]} px at ({cents[i, 0]:.0f}, {cents[i, 1]:.0f}) px: a reflection, or a laser spot "
        "so overexposed that its colour is gone (lower the exposure, or use a laser-off reference)"
    )


def _find(
    img: np.ndarray,
    colour: str,
    reference: np.ndarray | None,
    gamma: float,
    luma: bool,
    shrunk: dict | None = None,
    search: np.ndarray | None = None,
) -> tuple[list[Spot], list[Rejection]]:
    """The candidates of one laser colour that pass the physical gates, and those refused."""
    shrunk = {} if shrunk is None else shrunk
    refs: dict[int, np.ndarray] = {}
    cands = find_candidates(img, colour, reference, shrunk=shrunk, search=search)
    found, rejected = [], []
    for c in cands:
        others = [o for o in cands if o is not c]
        side = max(c.box[2] - c.box[0], c.box[3] - c.box[1])
        k = 1 if side <= MEASURE_SIDE else 2 ** int(np.ceil(np.log2(side / MEASURE_SIDE)))  # a pyramid
        if k <= 1:
            rs = measure_spot(img, c, colour, reference, others, gamma, luma)
        else:
            # A spot tens to hundreds of px wide is measured on a shrunk copy of the photo: its
            # centre is known to a fraction of its width anyway, and the fit stays small and fast.
            # It is fitted in the luma: the laser's channel of so large a spot is clipped over a
            # wide, speckle-ragged plateau, while the others still draw its profile.
            small = _octave(shrunk, img, k)
            if reference is not None and k not in refs:
                refs[k] = _shrink(reference, k)
            ref = refs.get(k)
            near = [_shrunk(o, k) for o in others]
            rs = [
                _full_rim(img, _grown(r, k), colour)
                for r in measure_spot(small, _shrunk(c, k), colour, ref, near, gamma, True, False)
            ]
        for r in rs:
            (rejected if isinstance(r, Rejection) else found).append(r)
    if img.ndim == 3 and found:
        if "white" not in shrunk:
            shrunk["white"] = white_cores(img)
        found = [counted(s, shrunk["white"]) for s in found]
    found = [_with_lopsided(img, s, colour) for s in found]
    return _ring_first(found), rejected


def _with_lopsided(img: np.ndarray, s: Spot, colour: str) -> Spot:
    """A spot with how lopsided its light is (:func:`vision.bare.lopsided`), in the full photo."""
    if s.evidence is None:
        return s
    ch = None if img.ndim == 2 else CHANNEL[colour]
    return replace(s, evidence=replace(s.evidence, lopsided=lopsided(img, ch, s.u, s.v, s.evidence.area)))


def _ring_first(spots: list[Spot]) -> list[Spot]:
    """A white core in a laser-coloured ring is measured by its core (:mod:`vision.ring`); the other
    rules' blobs around it hold its halo with whatever is near (a grey disc, a glint), and their
    centres are pulled off: spots within three core radii (+ 6 px) of a ringed core are its own, and
    so is their light."""
    rings = [s for s in spots if s.evidence is not None and (s.evidence.ring or 0.0) >= RING_MIN]
    if not rings:
        return spots

    def own(s: Spot, c: Spot) -> bool:
        reach = max(3 * np.sqrt(c.area / np.pi) + 6, np.sqrt(s.area / np.pi))
        return np.hypot(s.u - c.u, s.v - c.v) <= reach

    # A ringed core's light is its whole spot's: the flux of the blobs it absorbs, when larger.
    out = []
    for c in rings:
        flux = max([c.evidence.flux] + [s.evidence.flux for s in spots if s not in rings and own(s, c)])
        out.append(replace(c, evidence=replace(c.evidence, flux=flux)))
    return out + [s for s in spots if s not in rings and not any(own(s, c) for c in rings)]


def _full_rim(img: np.ndarray, r: Spot | Rejection, colour: str) -> Spot | Rejection:
    """A spot measured on a shrunk copy, with the rim centre of its clipped core
    (:func:`vision.bare.rim_centre`) measured in the full photo: a core of tens of px whose blob (its
    halo, a streak beside it) needs the shrunk copy is still centred to a pixel's fraction by its rim.
    Not for cores over :data:`~vision.bare.RIM_MAX_PX` (a spot hundreds of px wide, its plateau ragged
    with speckle)."""
    ev = r.evidence if isinstance(r, Spot) else None
    if ev is None or not RIM_MIN_PX <= ev.clipped_px <= RIM_MAX_PX or img.ndim != 3:
        return r
    half = int(2 * np.sqrt(ev.clipped_px / np.pi) + 10)
    h, w = img.shape[:2]
    x0, y0 = max(int(r.u) - half, 0), max(int(r.v) - half, 0)
    x1, y1 = min(int(r.u) + half + 1, w), min(int(r.v) + half + 1, h)
    clipped = img[y0:y1, x0:x1, CHANNEL[colour]] >= CLIP * full_scale(img)
    rim = rim_centre(clipped, (r.u - x0, r.v - y0))
    if rim is None:
        return r
    return replace(r, evidence=replace(ev, rim_centre=(rim[0] + x0, rim[1] + y0)))


def _shrunk(c: Candidate, k: int) -> Candidate:
    """A candidate in a copy of the photo shrunk by ``k`` (pixel centres: (u + 0.5) / k - 0.5)."""
    return replace(c, box=tuple(int(b) // k for b in c.box), u=(c.u + 0.5) / k - 0.5, v=(c.v + 0.5) / k - 0.5)


def _grown(r: Spot | Rejection, k: int) -> Spot | Rejection:
    """A spot or rejection measured on a copy shrunk by ``k``, in the full photo's pixels."""
    u, v = (r.u + 0.5) * k - 0.5, (r.v + 0.5) * k - 0.5
    if isinstance(r, Rejection):
        return replace(r, u=u, v=v)
    su = None if r.sigma_u is None else r.sigma_u * k
    sv = None if r.sigma_v is None else r.sigma_v * k
    p = r.pending
    if p is not None:  # its fit, when made, is in the shrunk copy's px too
        p = Pending(p.result, k * p.scale, None if p.fallback is None else _grown(p.fallback, k))
    ev = r.evidence
    if ev is not None:
        k2 = k * k
        ev = replace(
            ev,
            clipped_px=ev.clipped_px * k2,
            white_px=ev.white_px * k2,
            area=ev.area * k2,
            flux=ev.flux * k2,
            reach=ev.reach * k,
            rim_centre=None,  # a core's rim on a shrunk copy: too coarse
        )
    return replace(r, u=u, v=v, sigma_u=su, sigma_v=sv, area=r.area * k * k, evidence=ev, pending=p)


def _imagej_box(shape, spot: Spot, side: int) -> tuple[int, int, int, int]:
    """The box a person would draw around a spot: ``side`` px square, 0 for the whole photo."""
    h, w = shape[:2]
    if side <= 0:
        return 0, 0, w, h
    x0, y0 = int(round(spot.u - side / 2)), int(round(spot.v - side / 2))
    return max(x0, 0), max(y0, 0), min(x0 + side, w), min(y0 + side, h)
