"""Fitting the decision rule on labelled photos, and scoring it leaving one source out.

A labelled photo's candidates are measured once, through the physical gates only
(:func:`~vision.detect.measure_candidates`, as ``lasercal spots`` measures every photo); a
:class:`~vision.decide.DecisionRule` then decides which of them are spots
(:func:`~vision.detect.select`, as ``lasercal spots`` does next), so many rules are scored on the same
measurements, each exactly as the command would apply it. A photo is scored as the outside check
scores it: a labelled spot is found when a reported spot lies within max(4 px, 2 x its
``uncertainty_px``); a reported spot farther than 3 x ``radius_px`` + 6 px from every labelled and every
uncertain spot is false.

:func:`fit_rule` chooses the thresholds (a grid: the fewest misses plus false spots, each source
weighing the same; among equally good rules the middle one, farthest from both failure sides) and
then calibrates the probability (a logistic regression of "is a labelled spot" on the margin).
:func:`leave_one_source_out` fits on all sources but one and scores the one left out.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from lasercal.vision.decide import RULE, DecisionRule, judge, margin
from lasercal.vision.detect import measure_candidates, select
from lasercal.vision.errors import VisionError
from lasercal.vision.images import chroma_subsampled, read_image
from lasercal.vision.measure import check_photo, stage

# The grid the thresholds are chosen on. Theory bounds the rim shift of white light by 1; the
# dominance is the share of the strongest spot's light another spot must bring.
SHIFT_GRID = tuple(np.round(np.geomspace(1.2, 4.0, 16), 3))
CORE_GRID = tuple(np.round(np.geomspace(1.0, 2.5, 12), 3))
DOMINANCE_GRID = (0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5)
# How one-sided a spot's laser light may be (0: centred on it, 1: all on one side), and how large a share
# of the photo an unclipped spot may cover.
SIDE_GRID = (0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.6, 0.7, 0.8, 1.0)
SHARE_GRID = tuple(np.round(np.geomspace(1e-4, 0.1, 13), 6))
# Issue 55: the rim shift a colourless white core alone in the photo needs, and the share of the most
# laser-like candidate's luma rise another must bring.
BARE_GRID = (1.0, 1.05, 1.1, 1.15, 1.2, 1.3, 1.4, 1.6, 2.0)
ADDS_GRID = (0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9)
# How far from neutral (|ln paper_ratio|) the surface under a colourless core may be.
NEUTRAL_GRID = (0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0, 3.0)
# How far from point-symmetric a candidate among several may be, and how lopsided a clipped core must be
# for the rim of its saturation to centre it (vision.bare.lopsided: 0 symmetric, 1 all on one side).
LOPSIDED_GRID = (0.06, 0.08, 0.1, 0.12, 0.15, 0.18, 0.22, 0.27, 0.33, 0.4)
LEAN_GRID = (0.06, 0.08, 0.1, 0.11, 0.12, 0.13, 0.14, 0.15, 0.17, 0.19, 0.22, 0.26, 0.3, 1.0)
# Thresholds set to the highest of their equally good values, not the middle: the rim's centre is the
# coarser one (the outline's quantisation, a clip edge ragged by speckle and a 4:2:0 JPEG, against the
# fit's 0.02 px), so it replaces the fit only where the misses ask for it. The misses and false spots
# the fit counts cannot see a 0.5-px loss of precision, the phone sweep's measure.
HIGHEST = ("lean_min",)
# Each threshold's grid, by DecisionRule's field.
GRIDS = {
    "shift_min": SHIFT_GRID,
    "core_shift_min": CORE_GRID,
    "dominance": DOMINANCE_GRID,
    "side_max": SIDE_GRID,
    "share_max": SHARE_GRID,
    "bare_shift": BARE_GRID,
    "bare_neutral": NEUTRAL_GRID,
    "adds_share": ADDS_GRID,
    "lopsided_max": LOPSIDED_GRID,
    "lean_min": LEAN_GRID,
}
# Issue 55's thresholds: fitted (bench_vision_wild_loso.py) with the others held as RULE has them.
ISSUE_55 = ("bare_shift", "bare_neutral", "adds_share", "lopsided_max", "lean_min")


@dataclass(frozen=True)
class Labelled:
    """One labelled photo and its candidates, measured once.

    Attributes
    ----------
    source : str, the camera or set it comes from (the folder)
    name : str
    spots : list of dict, the labels (``x``, ``y``, ``uncertainty_px``, ``radius_px``), px
    uncertain : list of dict, spots that may or may not be laser light (never counted false)
    tries : dict, from :func:`~vision.detect.measure_candidates` (not yet judged); None when
        the photo is lost before any candidate (an error line in ``error``)
    error : str or None
    scores : dict, DecisionRule -> its :class:`Score` on this photo, for the rules already applied
        (:func:`score_of`)
    """

    source: str
    name: str
    spots: list
    uncertain: list
    tries: dict | None
    error: str | None = None
    # A photo's score under a rule never changes (its candidates are measured once), and fitting applies the
    # same rules again and again: each grid holds the current value, a sweep that changes nothing repeats
    # the last, and the folds of leave_one_source_out share all but one source and most of their rules
    # (bench_vision_loso's fits: 318,000 scorings, 65,000 of them distinct).
    scores: dict = field(default_factory=dict, compare=False, repr=False)


def measure_labelled(folder: Path, entries: list | None = None) -> list[Labelled]:
    """Measure the candidates of every photo of a folder labelled as ``labels.json`` (see the real
    photos' ``PROVENANCE.md``), as ``lasercal spots PHOTO`` reads and measures it."""
    entries = json.loads((folder / "labels.json").read_text()) if entries is None else entries
    out = []
    for e in entries:
        path = folder / e["file"]
        tries, error = None, None
        try:
            img = read_image(path)
            check_photo(img, str(path))
            with stage(str(path), "finding the laser spot"):
                tries = measure_candidates(img, "auto", None, 2.2, chroma_subsampled(path))
        except VisionError as exc:
            error = str(exc)
        uncertain = e.get("uncertain_spots") or []
        out.append(Labelled(e["file"].split("/")[0], e["file"], e["spots"], uncertain, tries, error))
    return out


@dataclass(frozen=True)
class Score:
    """Found labelled spots, false spots and distances (px) over some photos."""

    found: int = 0
    labelled: int = 0
    false: int = 0
    unmeasurable: int = 0
    photos: int = 0
    distances: tuple = ()

    def __add__(self, o: Score) -> Score:
        return Score(
            self.found + o.found,
            self.labelled + o.labelled,
            self.false + o.false,
            self.unmeasurable + o.unmeasurable,
            self.photos + o.photos,
            self.distances + o.distances,
        )

    @property
    def errors(self) -> int:
        """Misses plus false spots plus lost photos: what the rule is fitted to make fewest."""
        return self.labelled - self.found + self.false + self.unmeasurable

    @property
    def median(self) -> float:
        return float(np.median(self.distances)) if self.distances else float("nan")


def photo_spots(p: Labelled, rule: DecisionRule) -> list:
    """The spots ``lasercal spots --expect any`` reports for a measured photo under ``rule``."""
    if p.tries is None:
        return []
    try:
        return select(p.tries, p.name, None, rule)[1]
    except VisionError:
        return []


def score_photo(p: Labelled, spots: list) -> Score:
    """Score one photo's reported spots against its labels, as the outside check does."""
    dist, used = [], set()
    for lab in p.spots:
        d = [np.hypot(s.u - lab["x"], s.v - lab["y"]) for s in spots]
        j = int(np.argmin(d)) if d else -1
        if j >= 0 and j not in used and _finds(spots[j], lab):
            used.add(j)
            dist.append(float(d[j]))
    refs = p.spots + p.uncertain
    false = sum(_is_false(s, refs) for s in spots)
    lost = p.error is not None and "could not be measured" in p.error
    return Score(len(dist), len(p.spots), int(false), int(lost), 1, tuple(dist))


def _finds(s, lab: dict) -> bool:
    """Whether a reported spot finds a labelled one: within max(4 px, 2 x its uncertainty)."""
    return bool(np.hypot(s.u - lab["x"], s.v - lab["y"]) <= max(4.0, 2.0 * lab["uncertainty_px"]))


def _is_false(s, refs: list) -> bool:
    """Whether a reported spot is false: farther than 3 x radius + 6 px from every labelled spot."""
    return all(np.hypot(s.u - r["x"], s.v - r["y"]) > 3 * r.get("radius_px", 3.0) + 6 for r in refs)


def score_of(p: Labelled, rule: DecisionRule) -> Score:
    """:func:`score_photo` of the spots ``rule`` reports on ``p``, worked out once per photo and rule."""
    if rule not in p.scores:
        p.scores[rule] = score_photo(p, photo_spots(p, rule))
    return p.scores[rule]


def score(photos: list[Labelled], rule: DecisionRule) -> Score:
    return sum((score_of(p, rule) for p in photos), Score())


def _cost(photos: list[Labelled], rule: DecisionRule) -> float:
    """Errors per photo, averaged over the sources: each source weighs the same."""
    by: dict[str, list] = {}
    for p in photos:
        by.setdefault(p.source, []).append(p)
    # Summed per photo (errors add up): the sum of the Scores would join their distances for nothing.
    return float(np.mean([sum(score_of(p, rule).errors for p in ps) / len(ps) for ps in by.values()]))


def fit_rule(
    photos: list[Labelled], sweeps: int = 3, fields: tuple | None = None, base: DecisionRule | None = None
) -> DecisionRule:
    """The decision rule with the fewest errors on ``photos`` (each source weighing the same), with its
    probability calibrated on their candidates.

    The thresholds are chosen one at a time on their grids (:data:`GRIDS`; coordinate descent, from the
    middle of the grids, ``sweeps`` rounds): each is set to the middle of the grid values that make the
    fewest errors with the others held (in log space: the farthest from both kinds of failure that the
    data can tell apart; the highest for those of :data:`HIGHEST`). With ``fields`` (names of
    :data:`GRIDS`), only those are chosen, from ``base``'s values (default :data:`~vision.decide.RULE`),
    the others and the probability held as ``base`` has them.
    """
    names = tuple(GRIDS) if fields is None else tuple(fields)
    rule = DecisionRule(**{n: float(np.exp(np.median(np.log(g)))) for n, g in GRIDS.items()})
    if fields is not None:
        rule = RULE if base is None else base
    for _ in range(sweeps):
        before = rule
        for name in names:
            grid = np.array(GRIDS[name], float)
            costs = np.array([_cost(photos, replace(rule, **{name: float(v)})) for v in grid])
            best = grid[costs <= costs.min() + 1e-9]
            mid = best.max() if name in HIGHEST else np.exp(np.median(np.log(best)))
            rule = replace(rule, **{name: float(best[np.argmin(np.abs(np.log(best / mid)))])})
        if rule == before:
            break
    return calibrate(photos, rule) if fields is None else rule


def calibrate(photos: list[Labelled], rule: DecisionRule) -> DecisionRule:
    """``rule`` with ``offset`` and ``slope`` fitted by maximum likelihood: the probability that a
    candidate passing the physical gates is a labelled spot, against its margin."""
    x, y = [], []
    for p in photos:
        if p.tries is None:
            continue
        refs = p.spots + p.uncertain
        for spots, _ in p.tries.values():
            for s in spots:
                ev = judge(s.evidence, rule)
                hit = any(_finds(s, r) for r in p.spots)
                if hit or _is_false(s, refs):
                    x.append((1.0, margin(ev, rule), float(ev.clipped_px > 0)))
                    y.append(float(hit))
    x, y = np.array(x), np.array(y)
    if len(x) < 4 or y.min() == y.max():
        return rule

    def nll(w):  # with a weak prior (sigma 10) that keeps a separable set finite
        z = x @ w
        return float(np.sum(np.logaddexp(0, z) - y * z) + (w @ w) / 200)

    w = minimize(nll, np.array([0.0, 4.0, 0.0]), method="BFGS").x
    return replace(rule, offset=float(w[0]), slope=float(max(w[1], 0.1)), clipped=float(w[2]))


def leave_one_source_out(
    photos: list[Labelled], extra: list[Labelled] = (), fields: tuple | None = None
) -> dict:
    """Fit on every source but one (plus ``extra``, never held out), score the one left out (``fields``:
    as for :func:`fit_rule`).

    Returns
    -------
    dict source -> (DecisionRule fitted without it, its Score under that rule)
    """
    sources = sorted({p.source for p in photos})
    out = {}
    for src in sources:
        train = [p for p in photos if p.source != src] + list(extra)
        rule = fit_rule(train, fields=fields)
        out[src] = (rule, score([p for p in photos if p.source == src], rule))
    return out


def rendered(n: int, seed: int = 0) -> list[Labelled]:
    """Labelled photos from the phone renderer (:mod:`vision.render`), sampled wide: red or green,
    the spot's peak 0.3-100x the clipping level (far past it, its rim whitens), tilted 0-40 deg,
    speckle 0-0.3, lens blur 0.5-2 px (defocus), paper 0.3-0.8 under room light from warm
    (tungsten) to neutral, white-balanced, blooming 0.2-0.8, JPEG 4:2:0 quality 75-95; beside a
    printed cross, a red ink dot and a white glare (0.3-30x clipping); every fifth photo has no
    spot. 320 x 240 px at 0.3 mm/px.

    Returns
    -------
    list of Labelled, source "renderer" (the spot's label: its true centre, uncertainty 0.5 px and
    radius 2 sigma)
    """
    from lasercal.vision.render import (
        Glare,
        PhoneCamera,
        Photo,
        cross_print,
        ink_dot,
        look_down,
        render,
        tilted_spot,
    )

    view = look_down((320, 240), 0.3, centre=(450.0, 0.0))
    rng = np.random.default_rng([seed, 30])
    out = []
    for i in range(n):
        uv = rng.uniform([100, 80], [220, 160])
        sigma = rng.uniform(1.5, 3.0)
        spot = tilted_spot(
            *uv, sigma, float(np.exp(rng.uniform(np.log(0.3), np.log(100)))), rng.uniform(0, 40),
            rng.uniform(0, 180), speckle=rng.uniform(0, 0.3),
        )  # fmt: skip
        at = uv + rng.choice([-1, 1], (3, 2)) * rng.uniform(40, 70, (3, 2))
        xy = view.unproject(at)
        glare = Glare(*at[2], rng.uniform(2, 8), float(np.exp(rng.uniform(np.log(0.3), np.log(30)))))
        camera = PhoneCamera(bloom=rng.uniform(0.2, 0.8), jpeg=int(rng.integers(75, 96)))
        photo = Photo(
            view,
            prints=(cross_print(xy[0], 10), ink_dot(xy[1], rng.uniform(2, 5))),
            spots=() if i % 5 == 4 else (spot,),
            glares=(glare,),
            colour=("red", "green")[i % 2],
            paper=rng.uniform(0.3, 0.8),
            tint=(rng.uniform(0.6, 1.0), rng.uniform(0.85, 1.0), 1.0),  # B, G, R: warm to neutral
            gradient=rng.uniform(-0.2, 0.2),
            vignetting=rng.uniform(0, 0.15),
            psf=rng.uniform(0.5, 2.0),
            camera=camera,
        )
        img = render(photo, 9000 + i)
        labels = [] if i % 5 == 4 else [dict(x=uv[0], y=uv[1], uncertainty_px=0.5, radius_px=2 * sigma)]
        tries = measure_candidates(img, "auto", None, 2.2, True)
        out.append(Labelled("renderer", f"rendered {i}", labels, [], tries))
    return out


def lit_papers(n: int, seed: int = 0) -> list[Labelled]:
    """Labelled photos of coloured paper lit by a red laser or by warm broadband light, the light that
    comes closest to a red laser's rim: paper of any colour (linear reflectance 0.15-0.8 per
    channel), a Gaussian light of sigma 3-6 px peaking 3-30x the paper, clipped, gamma-encoded and
    saved as a 4:2:0 JPEG (quality 90). One photo in three holds a red laser (leaking 1-10 % of its
    light into green and blue: a spot); the others a warm lamp (diffuse: the paper's colour times a
    light with red 1.2-1.6x green, blue 0.6-1.0x green) or a warm glare (specular: the light's own
    colour), neither of them a spot. 200 x 160 px.

    Returns
    -------
    list of Labelled, source "lit paper"
    """
    import cv2

    rng = np.random.default_rng([seed, 31])
    yy, xx = np.mgrid[:160, :200]
    out = []
    for i in range(n):
        paper = rng.uniform(0.15, 0.8, 3)
        u, v, sigma = *rng.uniform([80, 60], [120, 100]), rng.uniform(3, 6)
        amp = float(np.exp(rng.uniform(np.log(3), np.log(30))))
        tint = np.array([rng.uniform(0.6, 1.0), 1.0, rng.uniform(1.2, 1.6)])  # BGR
        if i % 3 == 0:
            light = amp * paper.max() * np.array([*rng.uniform(0.01, 0.1, 2), 1.0])
        elif i % 3 == 1:
            light = amp * paper * tint
        else:
            light = amp * paper.max() * tint / tint.max()
        g = np.exp(-((xx - u) ** 2 + (yy - v) ** 2) / (2 * sigma**2))[..., None]
        lin = paper * (1 + 0.01 * rng.standard_normal((160, 200, 3))) + g * light
        img = np.clip(255 * np.clip(lin, 0, 1) ** (1 / 2.2), 0, 255).astype(np.uint8)
        img = cv2.imdecode(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1], cv2.IMREAD_COLOR)
        labels = [dict(x=u, y=v, uncertainty_px=0.5, radius_px=2 * sigma)] if i % 3 == 0 else []
        tries = measure_candidates(img, "auto", None, 2.2, True)
        out.append(Labelled("lit paper", f"lit paper {i}", labels, [], tries))
    return out


def wild(n: int, seed: int = 0) -> list[Labelled]:
    """Labelled photos of what an outside check on other cameras met (:mod:`vision.render_wild`): a spot
    whose halo lights a lighter disc or a glint beside it, a lamp whose red light an edge cuts, a large
    reddish surface beside a faint spot; ``n`` of each.

    Returns
    -------
    list of Labelled, source "wild" (the spot's label: its true centre, uncertainty 0.5 px, its core
    radius)
    """
    from lasercal.vision.render_wild import SCENES

    out = []
    for kind, draw in SCENES.items():
        for i in range(n):
            sc = draw(seed * 1000 + i)
            labels = [dict(x=sc.truth[0], y=sc.truth[1], uncertainty_px=0.5, radius_px=sc.radius)]
            tries = measure_candidates(sc.img, "auto", None, 2.2, True)
            out.append(Labelled("wild", f"{kind} {i}", labels, [], tries))
    return out


def wild55(n: int, seed: int = 0, first: int | None = None) -> list[Labelled]:
    """Labelled photos of issue 55's kinds (:data:`vision.render_wild.SCENES_55`: a colourless white core,
    a clipped core a flare streak leans, a red object beside a spot, a red-lit edge beside a spot), ``n``
    of each, ``n`` of the colourless core's counter-case (:func:`~vision.render_wild.two_white_cores`:
    no spot may be reported there but the true one, and none is right) and ``n`` colourless cores through
    a camera whose white balance misses (:func:`~vision.render_wild.colourless_off_balance`: a real
    camera's grey is a few % off neutral, the renderer's exactly neutral). The seeds are ``seed`` x 1000
    on, or ``first`` on when given.

    Returns
    -------
    list of Labelled, source "wild 55" (the spot's label: its true centre, uncertainty 0.5 px, its core
    radius; the counter-case's spot is an uncertain one, never false and never needed)
    """
    from lasercal.vision.render_wild import SCENES_55, colourless_off_balance, two_white_cores

    out = []
    more = {"two white cores": two_white_cores, "colourless off balance": colourless_off_balance}
    for kind, draw in dict(SCENES_55, **more).items():
        for i in range(n):
            sc = draw((seed * 1000 if first is None else first) + i)
            label = dict(x=sc.truth[0], y=sc.truth[1], uncertainty_px=0.5, radius_px=sc.radius)
            spots, uncertain = ([], [label]) if draw is two_white_cores else ([label], [])
            tries = measure_candidates(sc.img, "auto", None, 2.2, True)
            out.append(Labelled("wild 55", f"{kind} {i}", spots, uncertain, tries))
    return out
