"""Before/after error statistics and cross-validation (thesis Section 4.3, Figures 4.5-4.6).

For a set of laser spots meant to hit one reference point:

* scatter radius -- distance of each spot from the spots' own mean (mean, std), Figure 4.5;
* absolute error -- distance of each spot from the reference point (mean, max), Figure 4.6.

For a session, the spots are where a model says each captured beam lands: with the
nominal model they scatter as the thesis's "before" photos did, with the identified
model as its "after" photos (to first order the same errors, seen from the other side).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .identify import Identification, identify, predict_spots
from .model import RobotModel
from .session import Session


@dataclass(frozen=True)
class SpotStats:
    """Statistics of k spots aimed at one point (mm)."""

    n: int
    scatter_mean: float
    scatter_std: float
    error_mean: float
    error_max: float
    error_rms: float

    def as_dict(self) -> dict:
        return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def spot_stats(spots: np.ndarray, point: np.ndarray) -> SpotStats:
    """Scatter radius about the spots' mean and absolute error from the point (Figures 4.5-4.6).

    Parameters
    ----------
    spots : (k, 2) or (k, 3) array, mm (only x, y are used)
    point : (2,) or (3,) array, mm
    """
    xy = np.asarray(spots, dtype=float)[:, :2]
    radius = np.linalg.norm(xy - xy.mean(axis=0), axis=1)
    err = np.linalg.norm(xy - np.asarray(point, dtype=float)[:2], axis=1)
    return SpotStats(len(xy), float(radius.mean()), float(radius.std(ddof=1)) if len(xy) > 1 else 0.0, float(err.mean()), float(err.max()), float(np.sqrt(np.mean(err**2))))


def per_point(model: RobotModel, session: Session, mask: np.ndarray | None = None) -> dict:
    """:func:`spot_stats` per reference point of the spots ``model`` predicts for the captured configurations."""
    mask = np.ones(session.m, bool) if mask is None else mask
    spots, _ = predict_spots(model, session.q[mask], session.target[mask, 2])
    names = session.point[mask]
    return {nm: spot_stats(spots[names == nm], session.points[nm]) for nm in dict.fromkeys(names)}


def folds(session: Session, k: int, seed: int = 0) -> np.ndarray:
    """Fold index (m,) for K-fold cross-validation, stratified by point.

    Captures sharing a ``group`` column value (repeated captures of one pose) stay in one
    fold, so that no capture is predicted by a fit that saw it or its twin.
    """
    rng = np.random.default_rng(seed)
    groups = session.extra.get("group", np.arange(session.m).astype(str))
    out = np.empty(session.m, dtype=int)
    for nm in dict.fromkeys(session.point):
        sel = np.flatnonzero(session.point == nm)
        uniq = list(dict.fromkeys(groups[sel]))
        order = rng.permutation(len(uniq))
        fold_of = {uniq[g]: i % k for i, g in enumerate(order)}
        out[sel] = [fold_of[g] for g in groups[sel]]
    return out


@dataclass(frozen=True)
class CrossValidation:
    """K-fold held-out prediction errors (mm): per capture and summarised."""

    k: int
    errors: np.ndarray
    fold: np.ndarray
    nominal_errors: np.ndarray

    def as_dict(self) -> dict:
        e, e0 = self.errors, self.nominal_errors
        return {
            "folds": self.k,
            "holdout_rms_mm": float(np.sqrt(np.mean(e**2))),
            "holdout_mean_mm": float(e.mean()),
            "holdout_max_mm": float(e.max()),
            "nominal_rms_mm": float(np.sqrt(np.mean(e0**2))),
        }


def cross_validate(session: Session, method: str = "lm", k: int = 5, seed: int = 0, fit=None) -> CrossValidation:
    """Held-out in-plane error of each capture, predicted by a model fitted on the other folds.

    Parameters
    ----------
    session : Session
    method : str, identification method
    k : int, number of folds
    seed : int, fold assignment seed
    fit : callable(Session) -> RobotModel, optional override of the identification

    Returns
    -------
    CrossValidation
    """
    fit = fit or (lambda s: identify(s, method).model)
    f = folds(session, k, seed)
    err = np.empty(session.m)
    for i in range(k):
        test = f == i
        model = fit(session.subset(~test))
        spots, _ = predict_spots(model, session.q[test], session.target[test, 2])
        err[test] = np.linalg.norm(spots[:, :2] - session.target[test, :2], axis=1)
    spots0, _ = predict_spots(session.robot, session.q, session.target[:, 2])
    return CrossValidation(k, err, f, np.linalg.norm(spots0[:, :2] - session.target[:, :2], axis=1))


def solve_report(session: Session, ident: Identification, cv: CrossValidation | None = None) -> dict:
    """The statistics ``lasercal solve`` prints, as a JSON-ready mapping."""
    before = per_point(ident.nominal, session)
    used = ident.weights > 0
    after = per_point(ident.model, session, used)
    idf = ident.identifiability
    rep = {
        "method": ident.method,
        "converged": ident.converged,
        "iterations": ident.iterations,
        "seconds": round(ident.seconds, 4),
        "captures": session.m,
        "fit_rms_mm": round(ident.rms_mm, 6),
        "sigma_mm": round(ident.sigma_mm, 6),
        "outliers": [{"index": i, "line": int(session.lines[i]), "point": str(session.point[i])} for i in ident.outliers],
        "identifiability": {
            "parameters": idf.n_params, "rank": idf.rank, "condition": round(idf.condition, 3), "unidentifiable": idf.unidentifiable,
        },
        "points": {nm: {"before": before[nm].as_dict(), "after": after[nm].as_dict() if nm in after else None} for nm in before},
    }
    if ident.std_errors:
        rep["std_errors"] = {k: float(f"{v:.4g}") for k, v in ident.std_errors.items()}
    if cv is not None:
        rep["cross_validation"] = cv.as_dict()
    return rep
