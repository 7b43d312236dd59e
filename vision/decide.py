"""Stage 3 of spot detection: is a candidate laser light? Then its centre (stage 4, :mod:`vision.refine`).

:func:`measure_spot` measures one candidate (:mod:`vision.features`), rejects it when it is not
brighter than the paper in the laser's channel *and* in the luma (red ink: a phone's colour
correction lifts its red above the paper's, but it takes light away), when its rim does not shift
towards the laser's hue relative to the paper (white light of any kind, see
:func:`~vision.features._rim_shift`), when it is smaller than any lens-blurred spot, not a compact
ellipse, or a JPEG fringe beside ink (weak, next to darker pixels, or dark at its centre). The spots
left are ranked by the light they add (:attr:`~vision.spot.Evidence.strength`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from scipy import ndimage

from lasercal.vision.bare import rim_centre
from lasercal.vision.candidates import Candidate
from lasercal.vision.errors import SpotCountError
from lasercal.vision.features import (
    CLIP,
    LUMA,
    LUMA_CLIP,
    _box_array,
    _evidence,
    _ink,
    _label_at,
    _light_need,
    _linear,
    _others_max,
    _plane_background,
    _surround,
    _touches_border,
    compact_blob,
)
from lasercal.vision.images import all_at_least, full_scale
from lasercal.vision.refine import (
    FIT_STRAY,
    _border_noise,
    _centroid_sigma,
    _fit_profile,
    _laser_plane,
    _weighted_centroid,
)
from lasercal.vision.ring import RING_MIN, core_centre, ring_width, ringed_cores
from lasercal.vision.spot import CHANNEL, Evidence, Pending, Spot

MEASURE_SIDE = 160  # px: a candidate's box wider than this is measured on a shrunk copy
GROW_MAX = 2 * MEASURE_SIDE  # px: a box grows no further (larger spots are the coarse pass's)

# Laser light adds light: the luma rises by at least a quarter of the laser channel's weight in it
# times the channel's rise (a phone's colour matrix leaks up to half of it away: 0.48 measured for
# green on the renderer). Red objects and ink redden a patch while its other channels fall.
LIGHT_SHARE = 0.25


# A lens and demosaicing blur any spot by sigma >= 1 px: its blob (>= 15 % of its peak after the
# sigma-1 smoothing) covers >= 24 px. A hot photosite (one red 2x2 block) covers ~12.
MIN_BLOB = 20


# A surround whose laser channel outshines the others this much (linear) is no paper under room
# light: the laser's own halo fills the view (a tight crop), and the clipped core in it is the spot.
MONO = 20.0


# The size gate weighs spots clipped over less than this share of their blob: a laser's light spread over
# thousands of pixels clips in its core (a few % of a blob that holds a wide scatter halo, most of one far
# past clipping), while a lit surface touches clipping at most in a few grains of its texture.
SIZE_CLIPPED = 0.02


@dataclass(frozen=True)
class DecisionRule:
    """The parameters of the decision "laser light or not", from a candidate's :class:`Evidence`.

    White light, whatever the surface, gives a rim shift <= 1 in theory (see
    :func:`~vision.features._rim_shift`); a light whose colour temperature differs from the white
    balance, and the tone curve's shoulder, push it up (measured: up to ~2.1 for light that is not a
    laser). A spot exposed far past clipping keeps only a faint fringe around its clipped white core,
    and blooming whitens even that: a compact white core with any laser-ward fringe (rule "core")
    needs a lower shift than a spot without one (rule "rim"). The thresholds, the dominance and the
    probability's calibration are fitted on labelled candidates, leaving each source of real photos
    out in turn (``benchmarks/bench_vision_loso.py``).

    Attributes
    ----------
    shift_min : float, the rim shift a spot needs (rule "rim")
    core_shift_min : float, the rim shift a spot with a clipped white core needs (rule "core")
    dominance : float, with any number of spots expected, a spot whose strength is below this
        fraction of the photo's strongest is dropped: one laser adds about the same light
        wherever it lands, and red objects that pass every rule add far less
    side_max : float, the most one-sided a spot's laser-coloured light may be about it
        (:attr:`~vision.spot.Evidence.side`): a laser's light falls off all around its spot, while a
        grey disc or a glint in another spot's halo, or a lamp whose red light an edge cuts, is lit on
        one side
    share_max : float, the largest share of the photo a spot clipped over less than
        :data:`SIZE_CLIPPED` of its blob may cover (:attr:`~vision.spot.Evidence.share`): a laser's light
        spread over thousands of pixels clips; a reddish surface beside a shadow does not
    bare_shift : float, the rim shift a white clipped core alone in the photo needs (rule "bare", issue
        55; see :mod:`vision.bare`): laser-ward at all, where white light measures up to ~1.06
    bare_neutral : float, how far from neutral (``|ln paper_ratio|``,
        :attr:`~vision.spot.Evidence.paper_ratio`) the surface under a colourless core's rim may be for rule
        "bare": on a coloured surface a warm lamp's clipped white core shows as faint a laser-ward rim (the
        lit papers of :func:`vision.fit.lit_papers`)
    adds_share : float, of several candidates, one whose luma rises by less than this share of the most
        laser-like one's (:func:`vision.detect._adds`) is a coloured object, not light (issue 55)
    lopsided_max : float, of several candidates, one whose light is further than this from
        point-symmetric about its centre (:attr:`~vision.spot.Evidence.lopsided`) is refused while one
        that is not stays: a glow an edge cuts, not a beam (issue 55, :func:`vision.detect._point_symmetric`)
    lean_min : float, a clipped spot at least this lopsided whose precise fit strays from the rim of its
        saturation is centred on the rim (:func:`vision.detect._rim_centred`; issue 55)
    offset, slope, clipped : float, the probability
        ``1 / (1 + exp(-(offset + slope * margin + clipped * c)))`` of a candidate whose evidence
        clears its threshold by ``margin`` (see :func:`margin`), with ``c`` = 1 when its laser channel
        is clipped (a laser pointer's spot outshines room light many times over; a lit object
        seldom clips), else 0
    """

    # Fitted on the 24 real photos, 120 rendered ones, 60 of lit paper and 32 wild scenes
    # (bench_vision_loso.py, in-sample; its leave-one-source-out rows score the same procedure on
    # sources it did not see).
    shift_min: float = 2.471
    core_shift_min: float = 1.792
    dominance: float = 0.05
    side_max: float = 0.5
    share_max: float = 0.01
    # Issue 55's, fitted on the same real photos and issue 55's development renders (seeds 0-15 of each
    # kind) with the thresholds above held (bench_vision_wild_loso.py; its held-out rows score them).
    bare_shift: float = 1.15
    bare_neutral: float = 0.01
    adds_share: float = 0.85
    lopsided_max: float = 0.1
    lean_min: float = 0.12
    offset: float = -1.91
    slope: float = 0.99
    clipped: float = 1.30

    def probability(self, margin: float, clipped: bool = False) -> float:
        """The calibrated probability of laser light at a margin (see the class)."""
        z = self.offset + self.slope * margin + self.clipped * clipped
        return float(1 / (1 + np.exp(-np.clip(z, -50, 50))))


RULE = DecisionRule()
SHIFT_MIN = RULE.shift_min  # the rim shift a spot without a clipped white core needs


def has_core(ev: Evidence) -> bool:
    """Whether a spot has a clipped white core: clipped in the laser's channel and white in all three."""
    return ev.white_px > 0 and ev.clipped_px > 0


def judge(ev: Evidence, rule: DecisionRule = RULE) -> Evidence:
    """The evidence with the rule that takes it for laser light (or None) and its probability.

    Parameters
    ----------
    ev : Evidence measured by :func:`~vision.features._evidence`
    rule : DecisionRule

    Returns
    -------
    Evidence with ``rule`` ("rim", "core", "ring", "view", "bare", "grey" or None) and ``confidence``
    (probability)
    """
    if refusal(ev, rule) in ("side", "large"):  # its light's shape says it is no beam, whatever its colour
        return replace(ev, rule=None, confidence=0.0)
    if ev.colour is None:  # a grey photo: brightness is all there is
        return replace(ev, rule="grey", confidence=rule.probability(ev.lit, ev.clipped_px > 0))
    shift = ev.rim_shift or 0.0
    if shift >= rule.shift_min:
        name = "rim"
    elif has_core(ev) and shift >= rule.core_shift_min:
        name = "core"
    elif ev.ring is not None and ev.ring >= RING_MIN:
        # A clipped core inside a laser-coloured ring: the ring's colour over its threshold is the margin.
        return replace(ev, rule="ring", confidence=rule.probability(np.log(ev.ring / RING_MIN), True))
    elif ev.white_px and (ev.surround or 0.0) >= MONO:
        return replace(ev, rule="view", confidence=0.75)
    elif bare_alone(ev, rule):
        # A core so far past clipping that only a faint laser-ward rim is left, alone in the frame.
        return replace(ev, rule="bare", confidence=BARE_CONFIDENCE)
    else:
        name = None
    return replace(ev, rule=name, confidence=rule.probability(margin(ev, rule), ev.clipped_px > 0))


def refusal(ev: Evidence, rule: DecisionRule = RULE) -> str:
    """Why ``rule`` would refuse a candidate, a key of :data:`REASONS`: its laser-coloured light is
    one-sided ("side"), it is a large unclipped region ("large"), or else its colour is not the laser's
    ("white"; "several" where it is a colourless white core among several alike, see :func:`bare_core`).
    A spot the photo's edge cuts shows its light on one side only, whatever made it: its
    one-sidedness says nothing (LiamAG ``laser4.png``: 0.99), and its strength counts a quarter."""
    if (ev.side or 0.0) > rule.side_max and not ev.cut:
        return "side"
    if ev.share > rule.share_max and ev.clipped_fraction < SIZE_CLIPPED:
        return "large"
    if bare_core(ev, rule) and (ev.bare or 0) > 1:
        return "several"
    return "white"


def margin(ev: Evidence, rule: DecisionRule = RULE) -> float:
    """How far a candidate's evidence clears its rule: the log of its rim shift over the threshold
    of its rule (a clipped white core's, when it has one), or the log-margin of its brightness
    (:attr:`Evidence.lit`), whichever is smaller; the brightness alone on a grey photo."""
    if ev.colour is None:
        return float(ev.lit)
    thr = min(rule.shift_min, rule.core_shift_min) if has_core(ev) else rule.shift_min
    return float(min(np.log(max(ev.rim_shift or 0.0, 1e-9) / max(thr, 1e-9)), ev.lit))


REASONS = {
    "dim": "not brighter than the paper (printed marks?)",
    "white": "white, not laser-coloured (reflections?)",
    "shape": "not a compact ellipse (a wire, a frame or an object's edge?)",
    "unlit": "coloured but adds too little light (a red object, ink or a sensor defect?)",
    "fringe": "a faint coloured fringe beside ink or a ring (JPEG artefact)",
    "stray": "its centre falls off its own laser-coloured light (ink beside a spot?)",
    "side": "laser-coloured on one side only (lit by another spot's halo, or a lamp beside an edge?)",
    "large": "a large region that does not clip (a lit surface beside a shadow?)",
    "several": (
        "a white clipped blob with a faint laser-coloured rim, but the photo holds several alike: which "
        "is the laser it cannot say (lower the exposure, or take a laser-off photo: --reference)"
    ),
}


# Issue 55: a spot so far past clipping that its colour is gone (a white core, a thin rim a person still
# sees as coloured) is read when it is the only compact white clipped blob of its kind in the photo
# (DecisionRule.bare_shift), reported with a low probability and the advice to lower the exposure.
BARE_CONFIDENCE = 0.3


def bare_core(ev: Evidence, rule: DecisionRule = RULE) -> bool:
    """Whether a candidate is a white clipped core with a faint laser-ward rim (rim shift at least
    ``rule.bare_shift``) on a neutral surface (``rule.bare_neutral``), counted against the photo's other
    compact white blobs (:attr:`~vision.spot.Evidence.bare`)."""
    neutral = ev.paper_ratio is not None and abs(np.log(max(ev.paper_ratio, 1e-6))) <= rule.bare_neutral
    return ev.bare is not None and neutral and has_core(ev) and (ev.rim_shift or 0.0) >= rule.bare_shift


def bare_alone(ev: Evidence, rule: DecisionRule = RULE) -> bool:
    """Whether such a core is the photo's only compact white clipped blob of its size (rule "bare")."""
    return bare_core(ev, rule) and ev.bare == 1


@dataclass(frozen=True)
class Rejection:
    """Why a candidate is not a laser spot (``kind`` is a key of :data:`REASONS`)."""

    kind: str
    u: float
    v: float
    evidence: Evidence | None = None

    def describe(self) -> str:
        """One line: where, why, and the evidence when it was measured."""
        ev = "" if self.evidence is None else f" ({self.evidence.describe()})"
        return f"at ({self.u:.0f}, {self.v:.0f}) px: {REASONS[self.kind]}{ev}"


def measure_spot(
    img: np.ndarray,
    cand: Candidate,
    colour: str = "red",
    reference: np.ndarray | None = None,
    others: list[Candidate] = (),
    gamma: float = 2.2,
    luma: bool = False,
    split: bool = True,
) -> list[Spot | Rejection]:
    """Measure one candidate with the precise method, through the physical gates only: whether it is
    laser light by its colour is judged afterwards (:func:`judge`, by :func:`vision.detect.select`), so
    that one measurement serves every :class:`DecisionRule` (the command's and those fitted on the
    labelled photos, :mod:`vision.fit`) alike.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array
    cand : Candidate
    colour : "red" or "green"
    reference : laser-off photo like ``img``, or None
    others : the other candidates, whose pixels are kept out of the window
    gamma : float, the photo's encoding gamma (for the fit when ink lies under the spot)
    luma : bool, centroid on the luma instead of the laser's channel: a JPEG with
        chroma subsampling keeps only the luma at full resolution
    split : bool, measure apart two lights that one blob holds (:func:`_lobes`); off on a copy shrunk
        for a spot tens to hundreds of px wide, whose speckle grains part its luma as deeply (a glint
        beside it is measured apart by its own candidate at full resolution)

    Returns
    -------
    list of Spot (its evidence not yet judged: ``rule`` None) or Rejection when a physical gate refuses
    it: one for each light the box holds (a spot and a glare beside it are two)
    """
    rings: list[Spot] = []
    found = _measure_spot(img, cand, colour, reference, others, gamma, luma, split, rings)
    if not rings:
        return found
    ring = rings[0]
    # The precise fit, where it lands on the core, is the better centre; the ring adds to its evidence.
    for k, r in enumerate(found):
        if isinstance(r, Spot) and np.hypot(r.u - ring.u, r.v - ring.v) <= max(
            1.0, 0.25 * np.sqrt(ring.area / np.pi)
        ):
            flux = max(ring.evidence.flux, r.evidence.flux)
            ev = replace(r.evidence, ring=ring.evidence.ring, flux=flux)
            # Should the fit refuse the spot, its ringed core stands for it.
            later = Pending(r.pending.result, fallback=replace(ring, evidence=ev))
            found[k] = replace(r, evidence=ev, pending=later)
            return found
    return [ring] + [r for r in found if isinstance(r, Rejection)]


def finish(s: Spot) -> Spot | Rejection:
    """A spot with its precise centre (:class:`~vision.spot.Pending`: fitted once, when first asked for),
    or the rejection of a gate that refuses it once fitted (its centre strays off its own light)."""
    p = s.pending
    if p is None:
        return s
    out = p.result()
    if isinstance(out, str):
        if p.fallback is not None:
            return finish(p.fallback)
        return Rejection(out, s.u, s.v, s.evidence)
    k = p.scale
    u, v, su, sv = ((out[0] + 0.5) * k - 0.5, (out[1] + 0.5) * k - 0.5, out[2] * k, out[3] * k)
    return replace(s, u=u, v=v, sigma_u=su, sigma_v=sv, pending=None)


def _measure_spot(
    img: np.ndarray,
    cand: Candidate,
    colour: str,
    reference: np.ndarray | None,
    others: list[Candidate],
    gamma: float,
    luma: bool,
    split: bool,
    ring_out: list,
) -> list[Spot | Rejection]:
    """:func:`measure_spot` by the rules but the ring's; a ringed core found in the box is appended
    to ``ring_out`` (see :func:`_ringed_spot`)."""
    h, w = img.shape[:2]
    ch = CHANNEL[colour] if img.ndim == 3 else 0
    full = full_scale(img)
    x0, y0, x1, y1 = cand.box
    for attempt in range(4):  # grow the box until the spot no longer touches its border
        roi = img[y0:y1, x0:x1].astype(np.float32).reshape(y1 - y0, x1 - x0, -1)
        if reference is not None:
            roi = roi - reference[y0:y1, x0:x1].astype(np.float32).reshape(roi.shape)
        bg, noise = _plane_background(roi)
        delta = roi - bg
        sig = delta[..., ch]
        peak_d = float(sig.max())
        whole = (x0, y0, x1, y1) == (0, 0, w, h) or max(x1 - x0, y1 - y0) >= GROW_MAX
        # The spot's own light is laser-coloured: a white surface lit brighter than the paper the
        # border found (a white arm before a grey wall) is no reason to grow.
        lase = sig if roi.shape[2] == 1 else sig - _others_max(delta, ch)
        if whole or attempt == 3 or not _touches_border(lase, noise[ch], float(lase.max())):
            break
        gx, gy = (x1 - x0) // 2, (y1 - y0) // 2
        x0, y0, x1, y1 = max(x0 - gx, 0), max(y0 - gy, 0), min(x1 + gx, w), min(y1 + gy, h)
    # Not brighter than the paper: ink or a JPEG fringe, not light. A reference photo
    # removes ink and fringes, so fainter spots are believed then.
    contrast = (0.05 if reference is not None else 0.08) * full
    smooth = cv2.GaussianBlur(sig, (0, 0), 1.0)  # speckle would split a spot into several blobs
    plain = img[y0:y1, x0:x1].astype(np.float32).reshape(roi.shape)  # the photo itself, not a difference
    base = plain - delta  # what the photo would show without the laser (paper, or reference + paper)
    if img.ndim == 3 and _surround(base, ch, full, gamma) >= MONO:
        return [_core_in_halo(plain, delta, cand, (x0, y0), ch, full, noise, peak_d, colour, gamma)]
    if img.ndim == 3:
        ringed = _ringed_spot(
            plain, base, delta, cand, (x0, y0, w, h), ch, full, noise, peak_d, colour, gamma
        )
        if ringed is not None:
            if cand.ring_only:
                return [ringed]
            ring_out.append(ringed)
    if cand.ring_only:
        return [Rejection("white", cand.u, cand.v, None)]
    need = max(8 * noise[ch], contrast)
    thr = max(4 * noise[ch], 0.15 * peak_d)
    bright = (smooth > thr).astype(np.uint8)
    ink = _ink(plain, base, ch) if img.ndim == 3 else None
    if ink is not None:
        # A printed cross under the spot cuts it into pieces: bridge them over the ink.
        bright |= (ink & cv2.dilate(bright, np.ones((7, 7), np.uint8)).astype(bool)).astype(np.uint8)
    n, labels = cv2.connectedComponents(bright, connectivity=8)
    if n <= 1:
        ev = _evidence(plain, delta, None, ch, full, noise, peak_d, need, colour, gamma)
        return [Rejection("dim", cand.u, cand.v, ev)]
    # The brightest blob, unless it is another candidate's (a grown box may reach a brighter
    # neighbour, such as red ink, that is measured on its own).
    ours = labels > 0
    mine = _label_at(labels, cand.u - x0, cand.v - y0)
    for o in others:
        theirs = _label_at(labels, o.u - x0, o.v - y0)
        if theirs and theirs != mine:
            ours &= labels != theirs
    if not ours.any():
        ours = labels > 0
    iy, ix = np.unravel_index(np.argmax(np.where(ours, smooth, -np.inf)), sig.shape)
    exclude = np.zeros(sig.shape, bool)
    for o in others:
        ox, oy = int(round(o.u)) - x0, int(round(o.v)) - y0
        if 0 <= ox < sig.shape[1] and 0 <= oy < sig.shape[0] and labels[oy, ox] > 0:
            exclude |= labels == labels[oy, ox]
    raw = plain[..., ch]
    clipped = raw >= CLIP * full
    blob = labels == labels[iy, ix]
    exclude &= ~blob
    light = cv2.GaussianBlur(delta @ LUMA if img.ndim == 3 else sig, (0, 0), 0.5)  # a valley, not speckle
    # Ink under a spot cuts valleys into its light that are no gap between two lights.
    lobes = _lobes(light, blob, clipped) if split and (ink is None or not (ink & blob).any()) else [blob]
    box = _Box(img.ndim, cand, (x0, y0, w, h), ch, full, noise, delta, plain, base, smooth, ink, reference)
    return [
        _measure_blob(box, lobe, exclude | (blob & ~lobe), contrast, colour, gamma, luma) for lobe in lobes
    ]


@dataclass(frozen=True)
class _Box:
    """What :func:`_measure_spot` knows of a candidate's box, for :func:`_measure_blob`: the photo's
    dimensionality, the candidate, the box's origin and the photo's size (x0, y0, w, h) px, the laser's
    channel, full scale (DN), the paper's noise per channel (DN), the excess over the paper, the photo
    and the paper in the box (DN), the laser channel's excess smoothed over 1 px, printed ink (or
    None) and the reference photo (or None)."""

    ndim: int
    cand: Candidate
    where: tuple[int, int, int, int]
    ch: int
    full: float
    noise: np.ndarray
    delta: np.ndarray
    plain: np.ndarray
    base: np.ndarray
    smooth: np.ndarray
    ink: np.ndarray | None
    reference: np.ndarray | None
    # the arrays every light in the box makes alike, made for the first (features._box_array)
    memo: dict = field(default_factory=dict, compare=False, repr=False)


# Two lights in one blob (a spot and a glare or a lit disc in its halo): parts of it that stand apart in
# the luma, each by LOBE_DEPTH of its own height above the light that joins them, one of them clipped in
# the laser's channel. The laser's channel cannot tell them apart (a red halo keeps it near clipping
# between them); the luma, where the halo is dim, can. A speckled spot's clipped plateau is one part,
# and its grains do not stand apart by that much.
LOBE_DEPTH = 0.25
LOBE_MIN = 4  # px: a light's top (a 2x2 block), small enough for a spot in a copy shrunk for a larger one


def _lobes(smooth: np.ndarray, blob: np.ndarray, clipped: np.ndarray) -> list[np.ndarray]:
    """The lights a blob holds, each with the part of the blob its basin covers (a watershed of the
    smoothed luma ``smooth`` from each light's top); the blob itself when it holds one."""
    top = float(smooth[blob].max())
    for level in np.arange(0.9, 0.25, -0.1) * top:
        n, lab, stats, _ = cv2.connectedComponentsWithStats(
            ((smooth >= level) & blob).astype(np.uint8), connectivity=8
        )
        seeds = [
            i
            for i in range(1, n)
            if stats[i, cv2.CC_STAT_AREA] >= LOBE_MIN and level <= (1 - LOBE_DEPTH) * smooth[lab == i].max()
        ]
        if len(seeds) >= 2 and any(clipped[lab == i].any() for i in seeds):
            break
    else:
        return [blob]
    markers = np.zeros(blob.shape, np.int16)
    for k, i in enumerate(seeds, 1):
        markers[lab == i] = k
    markers[~blob] = len(seeds) + 1  # the rest of the box: a basin of its own
    relief = np.round(65535 * (1 - np.clip(smooth, 0, top) / top)).astype(np.uint16)
    basins = ndimage.watershed_ift(relief, markers)
    return [(basins == k) & blob for k in range(1, len(seeds) + 1)]


def _light_gates(box: _Box, blob: np.ndarray, contrast: float, colour: str, gamma: float):
    """The gates a light passes before its shape is weighed: bright enough over the paper's noise (a
    clipped one over the headroom left), its luma rising with its colour, no JPEG fringe beside ink.

    Returns
    -------
    Rejection, or (Evidence, faint): the light's evidence and whether it is faint (unclipped, under twice
    the light a spot needs)
    """
    cand, ch, full, noise = box.cand, box.ch, box.full, box.noise
    delta, plain, base = box.delta, box.plain, box.base
    _, _, w, h = box.where
    sig, ink = delta[..., ch], box.ink
    peak_d = float(sig[blob].max())
    need = max(8 * noise[ch], contrast)
    raw = plain[..., ch]
    clipped = _box_array(box.memo, "clipped", lambda: raw >= CLIP * full)
    if clipped[blob].any():
        # A clipped spot on bright paper exceeds it by no more than the headroom left: clipped and
        # half the headroom (or 8 sigma) brighter than the paper is bright enough, where the paper
        # is textured (a large spot's box holds the scene) at least 3 sigma.
        headroom = 0.5 * (full - _box_array(box.memo, "paper", lambda: float(np.median(base[..., ch]))))
        need = max(3 * noise[ch], min(8 * noise[ch], contrast, headroom))
    if peak_d < need or blob.sum() < MIN_BLOB:  # dim or tiny: no need to weigh its colour
        ev = _evidence(plain, delta, blob, ch, full, noise, peak_d, need, colour, memo=box.memo)
        return Rejection("dim", cand.u, cand.v, ev)
    ev = replace(
        _evidence(plain, delta, blob, ch, full, noise, peak_d, need, colour, gamma, ink, box.memo),
        share=blob.sum() / w / h,
    )
    # Laser light adds light: the luma rises too (a lone bright pixel is JPEG ringing or noise).
    if ev.light * full < _light_need(noise, full):
        return Rejection("dim", cand.u, cand.v, ev)
    if box.ndim == 3 and ev.light < LIGHT_SHARE * LUMA[ch] * ev.excess:
        return Rejection("unlit", cand.u, cand.v, ev)
    # A JPEG fringe is colour without light: its luma, kept at full resolution, barely rises.
    faint = ev.clipped_px == 0 and ev.light * full < 2 * _light_need(noise, full)
    if box.ndim == 3 and box.reference is None and peak_d < 0.15 * full and faint:
        # JPEG's coarse colour planes leave a faint laser-coloured fringe beside ink: a
        # weak blob next to pixels darker than the paper in the other channels is one.
        around = cv2.dilate(blob.astype(np.uint8), np.ones((11, 11), np.uint8)).astype(bool)
        if _box_array(box.memo, "other", lambda: _others_max(delta, ch))[around].min() < -0.15 * full:
            return Rejection("fringe", cand.u, cand.v, ev)
    return ev, faint


def _measure_blob(
    box: _Box,
    blob: np.ndarray,
    exclude: np.ndarray,
    contrast: float,
    colour: str,
    gamma: float,
    luma: bool,
) -> Spot | Rejection:
    """Measure one light of a candidate's box (its ``blob``; ``exclude``: other lights' pixels, kept out
    of its window), through the physical gates (see :func:`measure_spot`)."""
    gated = _light_gates(box, blob, contrast, colour, gamma)
    if isinstance(gated, Rejection):
        return gated
    ev, faint = gated
    cand, ch, full, noise = box.cand, box.ch, box.full, box.noise
    delta, plain, base = box.delta, box.plain, box.base
    x0, y0, w, h = box.where
    sig, smooth, ink = delta[..., ch], box.smooth, box.ink
    raw = plain[..., ch]
    clipped = _box_array(box.memo, "clipped", lambda: raw >= CLIP * full)
    # Whether its colour says laser light (a white reflection's does not) is judged later (judge).
    # A beam on a plane makes an ellipse (aspect 1/cos(tilt)): a blob that fills its own moment
    # ellipse poorly, or is longer than a beam at 66 deg makes, is a wire, a frame or an edge.
    if not compact_blob(blob):
        return Rejection("shape", cand.u, cand.v, ev)
    r_eq = np.sqrt(blob.sum() / np.pi)
    m = cv2.moments(blob.astype(np.uint8), binaryImage=True)
    start = (m["m10"] / m["m00"], m["m01"] / m["m00"])
    use_luma = luma and box.ndim == 3
    cen = _box_array(box.memo, "luma", lambda: delta @ LUMA) if use_luma else sig
    u, v, wgt = _weighted_centroid(cen, start, 1.1 * r_eq + 1, exclude)
    # A spot is brightest near its centre; a ring (JPEG fringe around ink) is dark there.
    if smooth[int(round(v)), int(round(u))] < 0.3 * smooth[blob].max() and ink is None and faint:
        return Rejection("fringe", cand.u, cand.v, ev)
    Y, X = _box_array(box.memo, "pixels", lambda: np.mgrid[: sig.shape[0], : sig.shape[1]])
    on_ink = ink is not None and bool(((np.hypot(X - u, Y - v) <= 1.5 * r_eq + 2) & ink).any())
    # Laser light lies where its colour is. Red ink on bright paper can clip in red and pass for a
    # clipped spot, but its luma is darker than the paper's: the luma centroid over it runs off to
    # whatever is brighter nearby, off the blob.
    near = cv2.dilate(blob.astype(np.uint8), np.ones((5, 5), np.uint8))
    if not _label_at(near, u, v):
        return Rejection("stray", cand.u, cand.v, ev)

    def centre():  # the precise fit (the slow part: only for a spot a rule accepts, see Pending)
        # Fit the profile in linear light over the spot and its flanks; clipped pixels bound it
        # from below, ink and other spots are left out.
        rec, under = (plain @ LUMA, base @ LUMA) if use_luma else (raw, base[..., ch])
        top = (LUMA_CLIP if use_luma else CLIP) * full
        lin_base = _linear(under, full, gamma)
        window = (np.hypot(X - u, Y - v) <= 2 * r_eq + 3) & ~exclude
        if ink is not None:
            window &= ~ink
        # The background's noise in linear units: the encoding's slope at the paper level.
        slope = gamma * float(np.median(np.clip(under[window] / full, 1e-3, 1))) ** (gamma - 1)
        n_rec = float(noise @ LUMA) if use_luma else float(noise[ch])
        d_fit, n_fit, clip_fit = _linear(rec, full, gamma) - lin_base, n_rec * slope, rec >= top
        if use_luma and not (clip_fit[window].any() or clipped[window].any()):
            # An unclipped spot in a 4:2:0 JPEG: the luma plus a little of the chroma (see CHROMA_WEIGHT).
            d_fit = (plain - base) @ _laser_plane(ch)
            n_fit = _border_noise(d_fit)
        ceiling = _linear(np.full_like(rec, top), full, gamma) - lin_base
        fit = _fit_profile(d_fit, window, clip_fit, ceiling, (u, v), r_eq, n_fit)
        # A fit that strays over a pixel from the windowed centroid fell for clutter in its wider
        # window (JPEG fringes of nearby ink): keep the centroid then.
        if fit is not None and (on_ink or np.hypot(fit[0] - u, fit[1] - v) <= FIT_STRAY):
            fu, fv, su, sv = fit
        elif on_ink:
            return "dim"
        else:
            fu, fv, (su, sv) = u, v, _centroid_sigma(cen, wgt, u, v)
        return "stray" if not _label_at(near, fu, fv) else (fu + x0, fv + y0, su, sv)

    # A blob cut by the photo's edge shows only part of its light, and its centre is extrapolated.
    cut = _cut_by_edge(blob, x0, y0, w, h)
    # The centre of its clipped core from the rim of the saturation (issue 55): kept beside the fit,
    # which leans when something joins the core on one side (vision.detect._rim_centred).
    rim = rim_centre(clipped & near.astype(bool), (u, v)) if clipped[blob].any() else None
    if rim is not None:
        ev = replace(ev, rim_centre=(rim[0] + x0, rim[1] + y0))
    return Spot(
        u + x0,
        v + y0,
        None,
        None,
        float(raw[blob].max()),
        bool(clipped[blob].any()),
        int(blob.sum()),
        on_ink=on_ink,
        evidence=replace(ev, cut=bool(cut)),
        pending=Pending(centre),
    )


def _core_in_halo(
    plain: np.ndarray,
    delta: np.ndarray,
    cand: Candidate,
    origin: tuple[int, int],
    ch: int,
    full: float,
    noise: np.ndarray,
    peak_d: float,
    colour: str,
    gamma: float,
) -> Spot | Rejection:
    """A spot whose own halo fills the box (a tight crop): its clipped white core, in a surround of
    nearly monochromatic laser light (see :data:`MONO`), is the spot; the centre is the core's.

    The surround is the laser's light, so the rim rule has no paper to compare with and the laser's
    channel is clipped over the core and most of the halo: only the core's outline is left. The
    sigma is a floor, the pixel quantisation of a disc's outline: each of its ~2 pi r edge pixels
    is in or out (variance 1/12) at a lever r cos(theta), so var = pi r**3 / (12 N**2) = 1 / (12 pi r)
    for N = pi r**2 pixels; speckle on the core's edge adds to it.
    """
    white = all_at_least(plain, LUMA_CLIP * full).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(white, connectivity=8)
    if n <= 1 or stats[1:, 4].max() < 4:
        return Rejection("dim", cand.u, cand.v, None)
    i = 1 + int(np.argmax(stats[1:, 4]))
    blob = labels == i
    ev = _evidence(plain, delta, blob, ch, full, noise, peak_d, peak_d, colour, gamma)
    if not ev.white_px or (ev.surround or 0.0) < MONO:
        return Rejection("white", cand.u, cand.v, ev)
    area = int(stats[i, 4])
    sigma = float(1 / np.sqrt(12 * np.pi * np.sqrt(area / np.pi)))
    u, v = cents[i]
    x0, y0 = origin
    raw = plain[..., ch]
    return Spot(u + x0, v + y0, sigma, sigma, float(raw[blob].max()), True, area, evidence=ev)


def _ringed_spot(
    plain: np.ndarray,
    base: np.ndarray,
    delta: np.ndarray,
    cand: Candidate,
    where: tuple[int, int, int, int],
    ch: int,
    full: float,
    noise: np.ndarray,
    peak_d: float,
    colour: str,
    gamma: float,
) -> Spot | None:
    """The spot of a white clipped core inside a ring of the laser's colour (see :mod:`vision.ring`),
    the core nearest the candidate's centre; None when the box holds no such core.

    ``where``: the box's origin (x0, y0) and the photo's (w, h), px. The centre is the core's centroid,
    its sigma the outline's quantisation (:func:`~vision.ring.core_centre`).
    """
    # A beam on a plane makes an elliptical core; a glare between wires or an object's lit face does not.
    ringed = [(c, dn) for c, dn in ringed_cores(plain, base, ch, full) if compact_blob(c)]
    if not ringed:
        return None
    x0, y0, w, h = where
    at = (cand.u - x0, cand.v - y0)
    centres = [core_centre(core) for core, _ in ringed]
    k = int(np.argmin([np.hypot(u - at[0], v - at[1]) for u, v, _ in centres]))
    core, colour_dn = ringed[k]
    u, v, sigma = centres[k]
    # Its light: the core and the lit pixels of its ring (the strength that ranks it is its flux).
    reach = 2 * int(ring_width(np.sqrt(core.sum() / np.pi))) + 1
    near = cv2.dilate(core.astype(np.uint8), np.ones((reach, reach), np.uint8)).astype(bool)
    light = core | (near & (delta[..., ch] > max(4 * noise[ch], 0.1 * peak_d)))
    ev = _evidence(plain, delta, light, ch, full, noise, peak_d, peak_d, colour, gamma)
    ev = replace(ev, ring=colour_dn)
    cut = _cut_by_edge(core, x0, y0, w, h)
    raw = plain[..., ch]
    return Spot(
        u + x0,
        v + y0,
        sigma,
        sigma,
        float(raw[core].max()),
        True,
        int(core.sum()),
        evidence=replace(ev, cut=bool(cut)),
    )


def _strength(s: Spot) -> float:
    """How convincing a spot is, to rank it against others (see :attr:`Evidence.strength`)."""
    return 0.0 if s.evidence is None else s.evidence.strength


def _dedupe(spots: list[Spot]) -> list[Spot]:
    """Drop spots found twice: two candidates of one spot converge within its radius."""
    out: list[Spot] = []
    # Of two measurements of one spot, keep the one whose blob holds more of its light.
    for s in sorted(spots, key=lambda s: -s.peak * s.area):
        if all(np.hypot(s.u - o.u, s.v - o.v) > max(3.0, np.sqrt(max(s.area, o.area) / np.pi)) for o in out):
            out.append(s)
    return out


CLOSE = 0.5  # a runner-up this close to the weakest kept spot, in strength, is not ruled out


def _where(s: Spot, rank) -> str:
    return f"({s.u:.1f}, {s.v:.1f}) px (confidence {s.evidence.confidence:.2f}, strength {rank(s):.3g})"


def _keep_strongest(spots: list[Spot], expect: int, name: str, rank=_strength) -> tuple[list[Spot], str]:
    """The ``expect`` most convincing spots, and a warning naming the others.

    One laser makes spots of about the same light (flux) wherever it lands; glints, LEDs and red
    objects that pass every rule are mostly far weaker. When the runner-up comes within
    :data:`CLOSE` of the weakest kept spot the photo cannot say which is the laser: both are named,
    with their confidence, and the photo is lost.

    Parameters
    ----------
    spots : list of Spot; expect : int; name : str, the photo's name
    rank : callable, Spot -> float, how convincing a spot is (its strength, times the predicted
        position's density when there is one)

    Raises
    ------
    SpotCountError
        The runner-up is close in strength to the weakest kept spot.
    """
    ranked = sorted(spots, key=rank, reverse=True)
    kept, rest = ranked[:expect], ranked[expect:]
    if rank(rest[0]) >= CLOSE * rank(kept[-1]):
        raise SpotCountError(
            f"{name}: {len(spots)} spots found where {expect} {'is' if expect == 1 else 'are'} expected, "
            f"close in evidence: {'; '.join(_where(s, rank) for s in ranked[:6])}"
            f"{' ...' if len(spots) > 6 else ''} (use --expect N for photos with several spots, or take "
            "a laser-off photo of the same view and pass it as --reference)"
        )
    others = "; ".join(_where(s, rank) for s in rest[:3]) + (" ..." if len(rest) > 3 else "")
    return kept, f"kept the {expect} most convincing spot{'s' * (expect > 1)}; weaker candidates: {others}"


def _dominant(spots: list[Spot], dominance: float, rank=_strength) -> tuple[list[Spot], str | None]:
    """With any number of spots expected: those at least ``dominance`` times as convincing as the
    strongest (see :attr:`DecisionRule.dominance`), and a warning naming the others.

    Returns
    -------
    kept : list of Spot; note : str or None
    """
    top = max(rank(s) for s in spots)
    kept = [s for s in spots if rank(s) >= dominance * top]
    rest = sorted((s for s in spots if rank(s) < dominance * top), key=rank, reverse=True)
    if not rest:
        return kept, None
    others = "; ".join(_where(s, rank) for s in rest[:3]) + (" ..." if len(rest) > 3 else "")
    return kept, (
        f"left out {len(rest)} candidate{'s' * (len(rest) > 1)} far weaker than the strongest spot "
        f"(below {dominance:.2g} of its strength): {others}; a laser-off photo (--reference) would tell"
    )


def _cut_by_edge(mask: np.ndarray, x0: int, y0: int, w: int, h: int) -> bool:
    """Whether a blob (mask (bh, bw) bool, its corner at x0, y0 px) touches the photo's (w, h) edge."""
    bh, bw = mask.shape
    cut = (x0 == 0 and mask[:, 0].any()) or (y0 == 0 and mask[0].any())
    return bool(cut or (x0 + bw == w and mask[:, -1].any()) or (y0 + bh == h and mask[-1].any()))
