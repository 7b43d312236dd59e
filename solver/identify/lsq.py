"""Least squares in the identifiable subspace, shared by every identification in ``solver``.

* Identifiability: SVD of the column-scaled Jacobian. Singular values below ``RANK_RTOL``
  of the largest mark parameter combinations the data cannot see; the fit moves only in
  the complement (they stay at their start values) and covariances live there too, so no
  rank-deficient normal matrix is ever inverted.
* Levenberg-Marquardt: MINPACK through ``scipy.optimize.least_squares(method='lm')`` with
  the analytic Jacobian.
* Robust loss: skipped least squares (a hard-redescending, truncated quadratic loss). Each
  capture's residual is tested by a Bonferroni-corrected chi-square test against a robust
  (median-based) noise scale; flagged captures get weight zero; test and refit repeat until
  the flagged set is stable.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.special import chdtri  # inverse survival function of chi-square (scipy.stats.chi2.isf)

RANK_RTOL = 1e-6
OUTLIER_ALPHA = 0.01  # family-wise false-flag rate of the outlier test


@dataclass(frozen=True)
class Identifiability:
    """What the data can and cannot see (SVD of the column-scaled Jacobian).

    Attributes
    ----------
    n_params : int
    rank : int
    condition : float, s_max / s_min over the identifiable subspace
    singular_values : (n_params,) array, of the column-scaled Jacobian
    unidentifiable : list of str, each null-space direction as its largest parameter components
    """

    n_params: int
    rank: int
    condition: float
    singular_values: np.ndarray
    unidentifiable: list


def identifiability(
    J: np.ndarray, names: list, rtol: float = RANK_RTOL
) -> tuple[Identifiability, np.ndarray]:
    """SVD identifiability report and the basis of the identifiable subspace.

    Parameters
    ----------
    J : (rows, p) array, the Jacobian
    names : list of p str

    Returns
    -------
    Identifiability, and (p, r) array B: parameter changes dx = B z span the identifiable subspace
    """
    scale = np.linalg.norm(J, axis=0)
    scale[scale < 1e-9 * scale.max()] = 1.0  # a column of round-off: do not blow it up to unit norm
    _, s, Vt = np.linalg.svd(
        J / scale, full_matrices=J.shape[0] < J.shape[1]
    )  # never the (rows x rows) U of a tall J
    s_full = np.zeros(J.shape[1])
    s_full[: len(s)] = s
    rank = int(np.sum(s_full > rtol * s_full[0]))
    null = []
    for v in Vt[rank:]:
        top = np.argsort(-np.abs(v))[:3]
        null.append(" ".join(f"{v[k]:+.2f}*{names[k]}" for k in top if abs(v[k]) > 0.05))
    report = Identifiability(J.shape[1], rank, float(s_full[0] / s_full[rank - 1]), s_full, null)
    return report, Vt[:rank].T / scale[:, None]


def covariance(Jz: np.ndarray, sigma: float) -> np.ndarray:
    """sigma^2 (Jz^T Jz)^-1 through the SVD of a full-column-rank Jz (never an explicit normal-matrix
    inverse)."""
    _, s, Vt = np.linalg.svd(Jz, full_matrices=False)
    return sigma**2 * (Vt.T / s**2) @ Vt


def flag_outliers(res: np.ndarray, w: np.ndarray, dof_ratio: float = 1.0) -> tuple[np.ndarray, float]:
    """Outlier mask by a chi-square(d) test on |residual| / sigma, sigma robust (from the median).

    Parameters
    ----------
    res : (m, d) array, residuals
    w : (m,) array, current weights (only w > 0 set the scale)
    dof_ratio : float, (rows - parameters) / rows: fitted residuals are smaller than the noise

    Returns
    -------
    mask (m,) of flagged captures, and the per-axis noise sigma
    """
    d = res.shape[1]
    r = np.linalg.norm(res, axis=1)
    sigma = float(np.median(r[w > 0]) / np.sqrt(chdtri(d, 0.5)) / np.sqrt(dof_ratio))
    cut = sigma * np.sqrt(chdtri(d, OUTLIER_ALPHA / len(r))) * np.sqrt(dof_ratio)
    return r > max(cut, 1e-4), sigma  # 0.1 um floor: exact data has round-off, not outliers


@dataclass(frozen=True)
class SubspaceFit:
    """Result of :func:`fit_subspace`.

    Attributes
    ----------
    v : (p,) array, the estimate
    cov : (p, p) array, its covariance (zero along unidentifiable directions)
    residuals : (m, d) array, of every capture (also the flagged ones)
    weights : (m,) array, 1 used, 0 flagged
    sigma : float, per-axis noise estimated from the used residuals
    identifiability : Identifiability
    converged : bool
    iterations : int, Jacobian evaluations
    history : list of dict
    span : (m, d, r) array, the Jacobian in the identifiable subspace at the solution: the
        residual directions the fit could absorb (nested-model tests project on it)
    constraint_span : (c, r) array, the same for the constraint rows (c = 0 without constraints)
    constraint_residuals : (c,) array
    """

    v: np.ndarray
    cov: np.ndarray
    residuals: np.ndarray
    weights: np.ndarray
    sigma: float
    identifiability: Identifiability
    converged: bool
    iterations: int
    history: list
    span: np.ndarray
    constraint_span: np.ndarray
    constraint_residuals: np.ndarray


def fit_subspace(
    residual: Callable,
    jacobian: Callable,
    v0: np.ndarray,
    names: list,
    robust: bool = True,
    w0: np.ndarray | None = None,
    constraints: Callable | None = None,
) -> SubspaceFit:
    """Levenberg-Marquardt in the identifiable subspace at v0, with the robust loss.

    Parameters
    ----------
    residual : v -> (m, d) array, per-capture residuals
    jacobian : v -> (m, d, p) array
    v0 : (p,) array, the start (unidentifiable combinations stay at its values)
    names : list of p str
    robust : bool, flag outliers and refit without them
    w0 : (m,) array, starting weights (e.g. captures already known to be gross outliers: 0)
    constraints : v -> ((c,) residual rows, (c, p) Jacobian), extra rows never weighted out
        (e.g. known distances, already divided by their standard deviation over sigma)

    Returns
    -------
    SubspaceFit
    """
    R0 = residual(v0)
    m, d = R0.shape
    p = len(v0)
    w = np.ones(m) if w0 is None else np.asarray(w0, dtype=float).copy()

    def rows(v, sw):
        r = (residual(v) * sw[:, None]).ravel()
        return r if constraints is None else np.r_[r, constraints(v)[0]]

    def jrows(v, sw):
        J = (jacobian(v) * sw[:, None, None]).reshape(m * d, p)
        return J if constraints is None else np.vstack([J, constraints(v)[1]])

    history, iterations = [], 0

    def run(v0, basis, z, w):
        nonlocal iterations
        sw = np.sqrt(w)
        sol = optimize.least_squares(
            lambda z: rows(v0 + basis @ z, sw),
            z,
            lambda z: jrows(v0 + basis @ z, sw) @ basis,
            method="lm",
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=200,
        )
        iterations += sol.njev
        res = residual(v0 + basis @ sol.x)
        history.append(
            {
                "pass": len(history) + 1,
                "rms_mm": float(np.sqrt(np.mean(np.sum(res[w > 0] ** 2, 1)))),
                "iterations": int(sol.njev),
                "status": int(sol.status),
            }
        )
        return sol, res

    ident, basis = identifiability(jrows(v0, np.ones(m)), names)
    sol, res = run(v0, basis, np.zeros(basis.shape[1]), w)
    r = basis.shape[1]
    dof_ratio = max(1 - r / (d * m), 0.05)
    if robust:
        for _ in range(5):
            flags, _ = flag_outliers(res, w, dof_ratio)
            if np.array_equal(flags, w == 0):
                break
            w = np.where(flags, 0.0, 1.0)
            sol, res = run(v0, basis, sol.x, w)
    v = v0 + basis @ sol.x
    used = w > 0
    dof = d * used.sum() - r + (0 if constraints is None else len(constraints(v)[0]))
    if dof <= 0:
        from lasercal.solver.errors import IdentificationError

        raise IdentificationError(f"{used.sum()} usable captures cannot identify {r} parameter combinations")
    sw = np.sqrt(w)
    sigma = float(np.sqrt(np.sum(rows(v, sw) ** 2) / dof))
    cov = basis @ covariance(jrows(v, sw) @ basis, sigma) @ basis.T
    rc, Jc = constraints(v) if constraints is not None else (np.zeros(0), np.zeros((0, p)))
    return SubspaceFit(
        v,
        cov,
        res,
        w,
        sigma,
        ident,
        bool(sol.status > 0),
        iterations,
        history,
        jacobian(v) @ basis,
        Jc @ basis,
        rc,
    )
