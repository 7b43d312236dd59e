"""Is the sheet flat and square? Eqs. S5, S6 tested against eq. S3 on a sheet session (issue 52).

Units: mm, rad; the shear g in mm per mm (reported in mm per m), the curvatures k in 1/mm, the curl in mm.

A sheet session's fit (:func:`solver.identify.spot.identify_lm`) holds the sheet as eq. S3: a plane, printed
at a scale along each axis. A taped paper curls and a printer shears (:mod:`solver.kinematics.sheet`,
eqs. S5, S6); neither is the robot's, and unmodelled they either raise the noise the fit reports or lean
on a joint. :func:`decide_sheet_shape` decides from the data whether to keep the four terms (g, kxx, kxy,
kyy):

1. the nested F test (eq. H1): with the flat fit's residuals r0 and the shaped fit's r1 on the same
   captures, each divided by the flat fit's noise of its capture (eq. K1's c_i; 1 without a camera),

       F = ((RSS0 - RSS1) / q) / (RSS1 / (n - rank1)),   q = rank1 - rank0,

   n the residual rows (2 per capture used), p = P(F(q, n - rank1) > F);
2. held out (``folds`` >= 2): the captures split into K folds, both models fitted on the rest and
   predicting each fold, in the same units; the gain is 1 - RSS1_ho / RSS0_ho (eq. H2).

On a session a camera measured, the shaped fit also holds the camera's view of the raised paper: a camera
that maps the paper through its markers' homography sees a raised spot displaced (0.3-0.5 mm on a paper
curled by 1.5 mm). Where the photos' markers told where the camera stood (captures.csv's ``camera_eye_x``
.. columns), that view is eq. S8 of :mod:`solver.kinematics.parallax`: fixed by the curl's own three terms
and the camera's place, no new term. Where they did not (an older session), it is eq. S7 of
:func:`solver.identify.spot.camera_warp_rows`, a free second-order field of six terms, the session's: the
test is then of the ten terms together (q is their rank), and only the sheet's are written to the model.

The terms are kept when p < alpha AND the gain is positive (with ``folds`` < 2 the F test decides alone,
and says so). Kept, the session is marked (:func:`modelled`) so that every later fit of it -- the
diagnosis's, the cross-validation's -- holds the sheet's shape: once named, modelled.

Not kept, the flat fit's residuals may still hold structure the noise does not explain (a bulge that is
not quadratic, a spot's glow): :func:`regions` says its size and where on the sheet, by a one-way analysis
of variance of the residuals over a 3 x 3 grid of the sheet (eq. H3: between-cell against within-cell
variance, F(2 (R - 1), 2 (n - R)); self-calibrated, so a camera whose stated sigma is too large cannot hide
it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.kinematics.sheet import SHAPE_KEYS, SheetPose, sheet_print

ALPHA = 0.01  # the F test's level (the diagnosis's family-wise level, solver.analysis.ALPHA)
MARK = "_sheet_shape_modelled"  # the session's meta key that makes every fit of it hold the shape
GRID = 3  # cells per sheet axis of eq. H3's analysis of variance


def modelled(session: Session) -> Session:
    """The session marked so that every ``lm`` fit of it fits eqs. S5, S6 (:func:`solver.identify.spot.
    identify_lm` reads the mark)."""
    return replace(session, meta={**session.meta, MARK: True})


def is_modelled(session: Session) -> bool:
    return bool(session.meta.get(MARK, False)) if isinstance(session.meta, dict) else False


@dataclass(frozen=True, eq=False)
class SheetShape:
    """The decision on the sheet's shape (module docstring).

    Attributes
    ----------
    tested : bool, False when the test could not run (``reason`` says why)
    kept : bool, the shape is modelled
    reason : str, why it was kept or not
    values : dict name -> (value, sigma): shear (mm per mm), curl_xx_per_mm, ... (1/mm)
    F, p : float, eq. H1; df : (q, n - rank1)
    holdout : dict, ``flat_mm``, ``shaped_mm`` (held-out RMS per axis, mm, over the captures used) and
        ``gain_percent`` (eq. H2, in units of each capture's noise); empty without folds
    curl_mm : float, the height field's range (max - min of h, eq. S6) over the captured area, mm
    shear_mm_per_m : float, 1000 g
    extent_mm : (2,) array, the captured area's size along the sheet's x, y, mm
    camera_warp_mm : float, RMS over the measured spots of the camera's view of the raised paper, mm (eq. S8
        of :mod:`solver.kinematics.parallax` from where each photo's camera stood; eq. S7 of
        :func:`solver.identify.spot.camera_warp_rows`, a free field, where no photo told it)
    regions : dict, eq. H3 on the flat fit's residuals: ``rms_mm`` {cell: RMS per axis of the cell's mean
        residual}, ``F``, ``p``, ``structure_mm`` (RMS of the cell means beyond their noise), ``worst``
    shaped : Identification or None, the shaped fit of the whole session
    """

    tested: bool
    kept: bool = False
    reason: str = ""
    values: dict = field(default_factory=dict)
    F: float = float("nan")
    p: float = float("nan")
    df: tuple = (0, 0)
    holdout: dict = field(default_factory=dict)
    curl_mm: float = 0.0
    shear_mm_per_m: float = 0.0
    extent_mm: tuple = (0.0, 0.0)
    camera_warp_mm: float = 0.0
    camera_view: str = ""  # "S8", "S7" or "" (no camera): which equation made camera_warp_mm
    regions: dict = field(default_factory=dict)
    shaped: object = None

    def as_dict(self) -> dict:
        """``solve --json``'s ``sheet_shape`` and the model file's ``identification.sheet_shape``."""
        return {
            "tested": self.tested,
            "kept": self.kept,
            "reason": self.reason,
            "terms": {k: {"value": float(v), "std_error": float(s)} for k, (v, s) in self.values.items()},
            "units": {
                "shear": "mm per mm",
                "curl": "1/mm (eq. S6)",
                "curl_mm": "mm",
                "shear_mm_per_m": "mm/m",
            },
            "F": None if not np.isfinite(self.F) else float(self.F),
            "df": [int(d) for d in self.df],
            "p_value": None if not np.isfinite(self.p) else float(self.p),
            "holdout": dict(self.holdout),
            "curl_mm": round(float(self.curl_mm), 6),
            "shear_mm_per_m": round(float(self.shear_mm_per_m), 6),
            "extent_mm": [round(float(e), 3) for e in self.extent_mm],
            "camera_warp_mm": round(float(self.camera_warp_mm), 6),
            "camera_view": self.camera_view,
            "regions": dict(self.regions),
        }


def printed_coords(session: Session, pose: SheetPose) -> np.ndarray:
    """Where each capture's spot (or aim) is printed, (m, 2) mm as printed (eq. S5)."""
    return sheet_print(pose.full_vector, np.asarray(session.target[:, :2], dtype=float))


def curl_range(pose: SheetPose, uv: np.ndarray) -> float:
    """Max - min of eq. S6's h over the box the layout points ``uv`` (k, 2) mm span, mm (a 41 x 41 grid)."""
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 41), np.linspace(lo[1], hi[1], 41))
    h = pose.height(np.column_stack([gx.ravel(), gy.ravel()]))
    return float(h.max() - h.min())


def regions(session: Session, residuals: np.ndarray, used: np.ndarray, pose: SheetPose) -> dict:
    """Eq. H3: the residuals' structure over a 3 x 3 grid of the sheet (module docstring).

    Parameters
    ----------
    session : Session, a sheet session
    residuals : (m, 2) array, the fit's residuals in the sheet's units, mm
    used : (m,) bool array, the captures to use (measured ones only, when a camera measured any)
    pose : SheetPose, the fitted sheet

    Returns
    -------
    dict: ``cells`` {"x-/y+" ...: {n, mean_mm [x, y]}}, ``F``, ``p``, ``structure_mm`` (RMS per axis of the
    cell means beyond their noise, weighted by their counts), ``worst`` (the cell with the largest mean)
    """
    uv = printed_coords(session, pose)[used]
    r = residuals[used]
    if len(r) < 4 * GRID * GRID:
        return {}
    edges = [np.quantile(uv[:, a], [1 / 3, 2 / 3]) for a in range(2)]
    cx, cy = np.digitize(uv[:, 0], edges[0]), np.digitize(uv[:, 1], edges[1])
    cell = cx * GRID + cy
    names = {0: "-", 1: "0", 2: "+"}
    out, between, within, R = {}, 0.0, 0.0, 0
    for c in range(GRID * GRID):
        sel = cell == c
        n = int(sel.sum())
        if n == 0:
            continue
        R += 1
        mean = r[sel].mean(axis=0)
        between += n * float(mean @ mean)
        within += float(np.sum((r[sel] - mean) ** 2))
        out[f"x{names[c // GRID]} y{names[c % GRID]}"] = {
            "n": n,
            "mean_mm": [round(float(v), 4) for v in mean],
        }
    d1, d2 = 2 * (R - 1), 2 * (len(r) - R)
    if R < 2 or d2 <= 0 or within <= 0:
        return {}
    F = (between / d1) / (within / d2)
    extra = max(between - d1 * within / d2, 0.0) / (2 * len(r))  # the cell means' variance beyond noise
    worst = max(out, key=lambda k: np.hypot(*out[k]["mean_mm"]))
    return {
        "cells": out,
        "F": float(F),
        "df": [d1, d2],
        "p": float(stats.f.sf(F, d1, d2)),
        "structure_mm": float(np.sqrt(extra)),
        "worst": worst,
    }


def _folds(m: int, k: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).permutation(m) % k


def shape_sizes(session: Session, shaped, anchors) -> tuple[dict, dict]:
    """The shaped fit's terms and their sizes.

    Parameters
    ----------
    session : Session, the sheet session
    shaped : Identification, the fit with eqs. S5, S6 (and on a camera session the camera's view of the
        raised paper: eq. S8 from where it stood, else eq. S7's free warp)
    anchors : (k, 2) array or None, the markers' centres (eq. S7), mm

    Returns
    -------
    values : dict key -> (value, standard error), the shape's terms (SHAPE_KEYS)
    sizes : dict, 'curl_mm' (:func:`curl_range`), 'shear_mm_per_m', and on a camera session
        'camera_warp_mm' (the camera's view's RMS over the measured spots, mm) and 'camera_view' ('S7' or
        'S8': which equation made it)
    """
    from lasercal.solver.identify.spot import camera_view, camera_warp_rows

    uv, meas = np.asarray(session.target[:, :2], dtype=float), session.measured

    pose = shaped.model.sheet
    sd = shaped.model.sheet_std or {}
    values = {k: (getattr(pose, k), sd.get(k, float("nan"))) for k in SHAPE_KEYS}
    sizes = {"curl_mm": curl_range(pose, uv), "shear_mm_per_m": 1000 * pose.shear}
    warp = shaped.extra.get("camera_warp")
    # the camera's view of the raised paper over the measured spots: eq. S7's free field, or eq. S8's from
    # where the camera stood
    field_mm = camera_warp_rows(uv, meas, anchors) @ warp if warp is not None else camera_view(session, pose)
    if meas.any() and np.ndim(field_mm):
        sizes["camera_warp_mm"] = float(np.sqrt(np.mean(np.sum(field_mm[meas] ** 2, axis=1))))
        sizes["camera_view"] = "S7" if warp is not None else "S8"
    return values, sizes


def shape_holdout(session: Session, used: np.ndarray, c: np.ndarray, folds: int, seed: int, robust, anchors):
    """The held-out check (eq. H2): the flat and the shaped model fitted on K - 1 folds, each predicting the
    last (a fitted camera warp, eq. S7, added: the same camera measured the held-out spots).

    Parameters
    ----------
    session : Session; used : (m,) bool array, the captures both full fits use
    c : (m,) array, each capture's noise scale (eq. K1's c_i)
    folds : int, K >= 2; seed : int; robust : bool; anchors : (k, 2) array or None (eq. S7)

    Returns
    -------
    dict, 'folds', 'flat_mm' and 'shaped_mm' (held-out RMS per axis, a camera session's over its measured
    captures), 'gain_percent' (100 (1 - RSS1_ho / RSS0_ho), each residual divided by its c_i)
    """
    from lasercal.solver.identify.spot import camera_warp_rows, identify_lm, plane_residuals

    m, meas = session.m, session.measured
    fold = _folds(m, folds, seed)
    ho = {False: np.full((m, 2), np.nan), True: np.full((m, 2), np.nan)}
    for i in range(folds):
        test = fold == i
        train = session.subset(~test)
        sub = session.subset(test)
        for shp in (False, True):
            try:
                f = identify_lm(train, robust=robust, shape=shp)
            except IdentificationError:
                continue
            warp = f.extra.get("camera_warp")  # the same camera measured the held-out spots (eq. S7)
            W = camera_warp_rows(sub.target[:, :2], sub.measured, anchors) @ warp if warp is not None else 0.0
            ho[shp][test] = plane_residuals(f.model, sub.q, sub) + W
    ok = used & np.all(np.isfinite(ho[False]), axis=1) & np.all(np.isfinite(ho[True]), axis=1)
    w0, w1 = ho[False][ok] / c[ok, None], ho[True][ok] / c[ok, None]
    kind = ok & (meas if meas.any() else True)
    return {
        "folds": folds,
        "flat_mm": float(np.sqrt(np.mean(ho[False][kind] ** 2))),
        "shaped_mm": float(np.sqrt(np.mean(ho[True][kind] ** 2))),
        "gain_percent": float(100 * (1 - np.sum(w1**2) / np.sum(w0**2))),
    }


def shape_verdict(p: float, alpha: float, holdout: dict) -> tuple[bool, str]:
    """Whether the terms are kept (p < alpha and, with folds, a positive held-out gain), and why."""
    significant = p < alpha
    better = holdout.get("gain_percent", 1.0) > 0
    if not significant:
        reason = f"not significant (p = {p:.3g} >= {alpha:g})"
    elif not better:
        worse = f"{holdout['gain_percent']:+.1f} %"
        reason = f"significant (p = {p:.3g}) but predicts held-out captures worse ({worse})"
    else:
        reason = f"significant (p = {p:.3g})" + (
            f" and predicts held-out captures better ({holdout['gain_percent']:+.1f} %)"
            if holdout
            else "; no folds: the F test decided alone"
        )
    return significant and better, reason


def decide_sheet_shape(
    session: Session, flat, folds: int = 5, seed: int = 0, alpha: float = ALPHA, robust: bool = True
) -> SheetShape | None:
    """Test eqs. S5, S6 against eq. S3 on a sheet session (module docstring).

    Parameters
    ----------
    session : Session, a laser session with ``frame: sheet`` (else None is returned)
    flat : Identification, the session's ``lm`` fit with the sheet flat (eq. S3)
    folds : int, K of the held-out check (< 2: the F test decides alone)
    seed : int, the folds' seed
    alpha : float, the F test's level
    robust : bool, the fits' robust loss

    Returns
    -------
    SheetShape or None (not a sheet session)
    """
    from lasercal.solver.identify.spot import identify_lm, marker_centres

    if session.frame != "sheet" or session.measurement != "laser" or flat.method != "lm":
        return None
    m = session.m
    c = np.asarray(flat.extra.get("scale", np.ones(m)), dtype=float)
    meas = session.measured
    used_flat = flat.weights > 0
    reg = regions(session, flat.residuals, used_flat & (meas if meas.any() else True), flat.model.sheet)
    uv = np.asarray(session.target[:, :2], dtype=float)
    anchors = marker_centres(session)
    extent = tuple(np.ptp(uv, axis=0).tolist())
    try:
        shaped = identify_lm(session, robust=robust, suspects=~used_flat, shape=True)
    except IdentificationError as e:
        return SheetShape(False, reason=f"the shaped fit failed: {e}", regions=reg, extent_mm=extent)
    used = used_flat & (shaped.weights > 0)
    r0, r1 = flat.residuals[used] / c[used, None], shaped.residuals[used] / c[used, None]
    rss0, rss1 = float(np.sum(r0**2)), float(np.sum(r1**2))
    q = shaped.identifiability.rank - flat.identifiability.rank
    dof = 2 * int(used.sum()) - shaped.identifiability.rank
    values, sizes = shape_sizes(session, shaped, anchors)
    if q <= 0 or dof <= 0:
        return SheetShape(
            True,
            False,
            "the data cannot see the sheet's shape beyond its plane",
            values,
            regions=reg,
            extent_mm=extent,
            **sizes,
        )
    F = ((rss0 - rss1) / q) / (rss1 / dof)  # eq. H1
    p = float(stats.f.sf(F, q, dof))
    holdout = shape_holdout(session, used, c, folds, seed, robust, anchors) if folds >= 2 else {}
    kept, reason = shape_verdict(p, alpha, holdout)
    return SheetShape(
        True,
        kept,
        reason,
        values,
        float(F),
        p,
        (q, dof),
        holdout,
        regions=reg,
        extent_mm=extent,
        shaped=shaped if kept else None,
        **sizes,
    )
