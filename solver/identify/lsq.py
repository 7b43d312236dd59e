"""Least squares in the identifiable subspace, shared by every identification in ``solver``.

* Identifiability: SVD of the column-scaled Jacobian. Singular values below ``RANK_RTOL``
  of the largest mark parameter combinations the data cannot see; the fit moves only in
  the complement (they stay at their start values) and covariances live there too, so no
  rank-deficient normal matrix is ever inverted.
* Levenberg-Marquardt: MINPACK through ``scipy.optimize.least_squares(method='lm')`` with
  the analytic Jacobian.
* Robust loss: skipped least squares. A capture is left out only with evidence against the
  noise model fitted on the rest: its externally studentised residual (leverage-corrected,
  sigma from the other rows; a left-out capture by its prediction error) is tested by an F
  test, Bonferroni-corrected over the captures (:func:`studentised_outliers`). Test and refit
  repeat until the flagged set is stable; a left-out capture that the refit predicts well
  comes back. With too few degrees of freedom for the test nothing is flagged.
* Nested fits: an extension of a geometric fit may flag only the captures the geometric fit flagged
  (``suspects``); it may bring them back. Otherwise a rejection cascades: with a few more columns the
  refit without the first flagged capture tightens its position's residuals and leaves its neighbour in
  recording order (real captures are serially correlated) a little further out, and the extension ends
  up compared with the geometry on other rows and paying more held-out for each row it drops
  (benchmarks/bench_extend_mukca.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize
from scipy.special import (
    chdtri,  # inverse survival function of chi-square (scipy.stats.chi2.isf)
    fdtrc,  # survival function of the F distribution (scipy.stats.f.sf)
)

from lasercal.solver.errors import IdentificationError
from lasercal.solver.identify.prior import Prior, noise_sigma

RANK_RTOL = 1e-6
# 1 - leverage below which a capture's residual direction is the fit's alone (its residual: round-off)
LEVERAGE_RTOL = 1e-10
# Family-wise false-flag rate of the outlier test. Strict on purpose: the test exists for gross mistakes
# (a capture logged against the wrong point or socket: tens of noise sigmas, flagged at any level), while
# real captures have heavier tails than the Gaussian noise model -- at 0.01 the four MUKCa Pandas lose
# 0-4 valid rows per fold (1.3-1.9 mm in positions of 0.2-0.5 mm RMS) and one held-out fold gets 3.8 %
# worse than plain least squares; at 1e-6 the worst fold is 1.5 % (benchmarks/bench_extend_mukca.py).
OUTLIER_ALPHA = 1e-6


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
    null_space : (n_params, n_params - rank) array, the unidentifiable directions in parameter units
        (columns of V past the rank, unscaled; :mod:`solver.identify.degenerate` names them)
    """

    n_params: int
    rank: int
    condition: float
    singular_values: np.ndarray
    unidentifiable: list
    null_space: np.ndarray


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
    report = Identifiability(
        J.shape[1], rank, float(s_full[0] / s_full[rank - 1]), s_full, null, Vt[rank:].T / scale[:, None]
    )
    return report, Vt[:rank].T / scale[:, None]


def thin_svd(A: np.ndarray) -> tuple:
    """U, s, Vt of A (full_matrices=False): LAPACK's divide and conquer (gesdd), and on the rare finite matrix
    where it does not converge (a fold of DLR's Justin with a joint map: 1640 x 308) the QR iteration
    (gesvd), slower and sure."""
    try:
        return np.linalg.svd(A, full_matrices=False)
    except np.linalg.LinAlgError:
        from scipy.linalg import svd

        return svd(A, full_matrices=False, lapack_driver="gesvd")


def covariance(Jz: np.ndarray, sigma: float) -> np.ndarray:
    """sigma^2 (Jz^T Jz)^-1 through the SVD of a full-column-rank Jz (never an explicit normal-matrix
    inverse)."""
    _, s, Vt = thin_svd(Jz)
    return sigma**2 * (Vt.T / s**2) @ Vt


def hat_trace(A: np.ndarray, k: int) -> float:
    """tr H of the first k rows (the data's): H = J (A^T A)^-1 J^T, A = U S V^T the stacked rows (data J,
    then constraints and the prior's rows at the current sigma), J = U_k S V^T, so tr H = |U_k|_F^2.

    Bounded by the rank whatever sigma is: the form tr(J C J^T) / sigma^2 lost every digit once sigma
    was small (exact data), where a direction only the prior holds has a singular value ~ sigma.
    """
    U = thin_svd(A)[0]
    return float(np.sum(U[:k] ** 2))


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


def studentised_outliers(
    res: np.ndarray,
    Jw: np.ndarray,
    w: np.ndarray,
    J_left: np.ndarray,
    groups: np.ndarray | None = None,
    alpha: float = OUTLIER_ALPHA,
) -> np.ndarray:
    """Captures whose residual is an outlier against the noise model fitted on the rest.

    Fitted capture i (d rows): q_i = e_i^T (I - H_ii)^-1 e_i with H = Jw (Jw^T Jw)^-1 Jw^T the hat
    matrix; externally studentised T_i = q_i / (d s_(i)^2) ~ F(d, dof_g - d) with
    s_(i)^2 = (RSS_g - q_i) / (dof_g - d). Left-out capture: q_i = e_i^T (I + J_i (Jw^T Jw)^-1
    J_i^T)^-1 e_i (its prediction error), s^2 = RSS_g / dof_g, T_i ~ F(d, dof_g). RSS_g and
    dof_g = d n_g - trace(H_gg) belong to the capture's group: each tool position keeps its own
    noise level (real positions differ several-fold), so a noisy but consistent position is not
    mistaken for outliers. Flagged when m p_i < alpha (Bonferroni over the captures).

    Parameters
    ----------
    res : (m, d) array, residuals of every capture, mm
    Jw : (rows, r) array, the weighted Jacobian of the fitted rows in the identifiable subspace
        (capture rows first, d per capture, zero rows for left-out captures; then constraint rows)
    w : (m,) array, 1 fitted, 0 left out
    J_left : (m, d, r) array, unweighted Jacobian of every capture (used for the left-out ones)
    groups : (m,) array of labels, the noise groups (default: one)
    alpha : float, family-wise false-flag rate

    Returns
    -------
    (m,) bool array of flagged captures (none in a group with dof_g - d < 1: no test is possible)
    """
    m, d = res.shape
    U, s, Vt = thin_svd(Jw)
    r = int(np.sum(s > RANK_RTOL * s[0])) if s.size else 0
    U, s, Vt = U[:, :r], s[:r], Vt[:r]
    fitted = w > 0
    eye = np.eye(d)
    Ui = U[: d * m].reshape(m, d, r)
    H = Ui @ np.swapaxes(Ui, 1, 2)  # (m, d, d) leverage blocks
    A = J_left @ (Vt.T / s)  # (m, d, r): J_i V S^-1
    C = np.where(fitted[:, None, None], eye - H, eye + A @ np.swapaxes(A, 1, 2))
    # a direction of leverage 1 (a parameter only this capture sees, e.g. a joint map's knot) has a
    # residual of 0 whatever the noise: untestable, left out of q_i (pseudo-inverse, not a singular solve)
    Cp = np.linalg.pinv(C, rcond=LEVERAGE_RTOL, hermitian=True)
    qi = np.einsum("md,md->m", res, (Cp @ res[..., None])[..., 0])
    groups = np.zeros(m, int) if groups is None else np.asarray(groups)
    flags = np.zeros(m, bool)
    for g in dict.fromkeys(groups):
        sel = groups == g
        fit_g = sel & fitted
        rss = float(np.sum(res[fit_g] ** 2))
        dof = d * int(fit_g.sum()) - float(np.trace(H[fit_g], axis1=1, axis2=2).sum())
        if dof - d < 1 or rss <= 0:
            continue
        s2 = np.where(fitted[sel], (rss - qi[sel]) / (dof - d), rss / dof)
        with np.errstate(over="ignore"):  # a residual far beyond a near-zero scale: T = inf, p = 0
            T = qi[sel] / (d * np.maximum(s2, 1e-300))
        p = np.where(fitted[sel], fdtrc(d, dof - d, T), fdtrc(d, dof, T))
        flags[sel] = (p * m < alpha) & (np.sqrt(qi[sel]) > 1e-4)  # 0.1 um floor: round-off is no outlier
    return flags


@dataclass(frozen=True)
class SubspaceFit:
    """Result of :func:`fit_subspace`.

    Attributes
    ----------
    v : (p,) array, the estimate
    cov : (p, p) array, its covariance (zero along directions neither the data nor a prior determine;
        with a prior, eq. P4 of :mod:`solver.identify.prior`)
    residuals : (m, d) array, of every capture (also the flagged ones)
    weights : (m,) array, 1 used, 0 flagged
    sigma : float, per-axis noise estimated from the used residuals (with a prior: eq. P3)
    identifiability : Identifiability, of the data and constraints alone (a prior does not enter it)
    converged : bool
    iterations : int, Jacobian evaluations
    history : list of dict
    span : (m, d, r) array, the Jacobian in the identifiable subspace at the solution: the
        residual directions the fit could absorb (nested-model tests project on it)
    constraint_span : (c, r) array, the same for the constraint rows (c = 0 without constraints)
    constraint_residuals : (c,) array
    prior : Prior or None, the prior of a MAP fit
    dof : float, residual degrees of freedom d m_used - tr H (eq. P3; without a prior, d m_used - rank)
    leverage : (m,) array, each capture's share of tr H (the diagonal of the hat matrix summed over its d
        rows, constraints and prior included; 0 for a flagged capture): E|r_i|^2 = (d - h_i) sigma_i^2
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
    prior: Prior | None = None
    dof: float = 0.0
    leverage: np.ndarray | None = None


_SIGMA_RTOL = 1e-2  # the noise fixed point (eq. P3) is reached when sigma changes less than this
_SIGMA_PASSES = 12  # at most this many refits for it (3-5 usually)


@dataclass(eq=False)
class SubspaceLM:
    """:func:`fit_subspace`'s problem and its passes: the stacked rows [sqrt(w_i) r_i(v); constraints;
    prior] (the prior's rows weighted by the current noise ``sigma``, eq. P2 of
    :mod:`solver.identify.prior`) and their Jacobian, the Levenberg-Marquardt passes in a subspace v0 + B z,
    the robust test-and-refit and the noise's fixed point (eq. P3).

    Attributes
    ----------
    residual, jacobian, constraints, prior, robust, groups, suspects : as :func:`fit_subspace`'s
    m, d, p : int, captures, residual rows per capture, parameters
    sigma : float, the current per-axis noise (the prior's rows are weighted by it)
    history : list of dict, per pass 'pass', 'rms_mm', 'iterations', 'status'
    iterations : int, Jacobian evaluations so far
    """

    residual: Callable
    jacobian: Callable
    constraints: Callable | None
    prior: Prior | None
    robust: bool
    groups: np.ndarray | None
    suspects: np.ndarray | None
    m: int
    d: int
    p: int
    sigma: float
    history: list = field(default_factory=list)
    iterations: int = 0

    def extra_rows(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The constraints' rows, then the prior's (weighted by the current noise sigma): ((c,), (c, p))."""
        r, J = (np.zeros(0), np.zeros((0, self.p))) if self.constraints is None else self.constraints(v)
        if self.prior is not None:
            rp, Jp = self.prior.rows(v, self.sigma)
            r, J = np.r_[r, rp], np.vstack([J, Jp])
        return r, J

    def rows(self, v: np.ndarray, sw: np.ndarray) -> np.ndarray:
        """The stacked rows (m d + c,) at v, the captures' weighted by sw (m,)."""
        return np.r_[(self.residual(v) * sw[:, None]).ravel(), self.extra_rows(v)[0]]

    def jrows(self, v: np.ndarray, sw: np.ndarray) -> np.ndarray:
        """d :meth:`rows` / dv, (m d + c, p)."""
        J = (self.jacobian(v) * sw[:, None, None]).reshape(self.m * self.d, self.p)
        return np.vstack([J, self.extra_rows(v)[1]])

    def run(self, v0: np.ndarray, basis: np.ndarray, z: np.ndarray, w: np.ndarray):
        """One Levenberg-Marquardt pass over z in v = v0 + basis z from z, captures weighted by w (m,); its
        record joins :attr:`history`. Returns the solution (OptimizeResult) and the residuals (m, d)."""
        sw = np.sqrt(w)
        sol = optimize.least_squares(
            lambda z: self.rows(v0 + basis @ z, sw),
            z,
            lambda z: self.jrows(v0 + basis @ z, sw) @ basis,
            method="lm",
            xtol=1e-12,
            ftol=1e-12,
            gtol=1e-12,
            max_nfev=200,
        )
        self.iterations += sol.njev
        res = self.residual(v0 + basis @ sol.x)
        self.history.append(
            {
                "pass": len(self.history) + 1,
                "rms_mm": float(np.sqrt(np.mean(np.sum(res[w > 0] ** 2, 1)))),
                "iterations": int(sol.njev),
                "status": int(sol.status),
            }
        )
        return sol, res

    def robust_fit(self, v0: np.ndarray, basis: np.ndarray, z: np.ndarray, w: np.ndarray):
        """LM, then test-and-refit until the flagged set is stable (:func:`studentised_outliers`). Returns
        the solution, the residuals (m, d) and the weights (m,)."""
        sol, res = self.run(v0, basis, z, w)
        if not self.robust:
            return sol, res, w
        # flags can cycle (few captures: a capture is an outlier only while another one is fitted);
        # a weight pattern fitted before is not refitted: its fit is the same up to the LM tolerance
        fits = {w.tobytes(): (sol, res, self.history[-1])}
        for _ in range(8):
            v = v0 + basis @ sol.x
            sw = np.sqrt(w)
            flags = studentised_outliers(
                res, self.jrows(v, sw) @ basis, w, self.jacobian(v) @ basis, self.groups
            )
            if self.suspects is not None:
                flags &= self.suspects
            if np.array_equal(flags, w == 0):
                break
            w = np.where(flags, 0.0, 1.0)
            if w.tobytes() in fits:
                sol, res, h = fits[w.tobytes()]
                self.history.append({**h, "pass": len(self.history) + 1, "iterations": 0})
            else:
                sol, res = self.run(v0, basis, sol.x, w)
                fits[w.tobytes()] = (sol, res, self.history[-1])
        return sol, res, w

    def noise_fixed_point(self, v0: np.ndarray, basis: np.ndarray, w: np.ndarray):
        """The robust fit from z = 0; with a prior, refitted until the noise sigma and the fit agree (eq. P3:
        sigma from the residual sum of squares over dof = d m_used - tr H).

        Returns
        -------
        sol : OptimizeResult; res : (m, d) array; w : (m,) array
        dof : float, the last pass's residual degrees of freedom (None without a prior)
        """
        z, dof = np.zeros(basis.shape[1]), None
        for _ in range(_SIGMA_PASSES if self.prior is not None else 1):
            sol, res, w = self.robust_fit(v0, basis, z, w)
            z = sol.x
            if self.prior is None:
                break
            v = v0 + basis @ z
            used = w > 0
            dof = self.d * used.sum() - hat_trace(
                self.jrows(v, np.sqrt(w)) @ basis, self.m * self.d
            )  # eq. P3
            rss = float(np.sum(res[used] ** 2))
            new = noise_sigma(self.prior.noise, self.prior.noise_dof, rss, dof)
            done = abs(new / self.sigma - 1) < _SIGMA_RTOL
            self.sigma = new
            if done:
                break
        return sol, res, w, dof


def fit_subspace(
    residual: Callable,
    jacobian: Callable,
    v0: np.ndarray,
    names: list,
    robust: bool = True,
    w0: np.ndarray | None = None,
    constraints: Callable | None = None,
    groups: np.ndarray | None = None,
    suspects: np.ndarray | None = None,
    prior: Prior | None = None,
) -> SubspaceFit:
    """Levenberg-Marquardt in the identifiable subspace at v0, with the robust loss; MAP with a prior.

    Parameters
    ----------
    residual : v -> (m, d) array, per-capture residuals
    jacobian : v -> (m, d, p) array
    v0 : (p,) array, the start (combinations neither the data nor the prior identify stay at its values)
    names : list of p str
    robust : bool, flag outliers (:func:`studentised_outliers`) and refit without them
    w0 : (m,) array, starting weights (e.g. captures suspected as gross outliers: 0; they are
        re-tested and come back when the fit predicts them)
    constraints : v -> ((c,) residual rows, (c, p) Jacobian), extra rows never weighted out
        (e.g. known distances, already divided by their standard deviation over sigma)
    groups : (m,) array of labels, noise groups of the outlier test (e.g. tool positions)
    suspects : (m,) bool array, the only captures the outlier test may flag (e.g. those the geometric fit
        flagged, for an extension of it); they start left out and come back when the fit predicts them.
        Default: every capture
    prior : Prior or None, the MAP fit of :mod:`solver.identify.prior` (eqs. P2-P4): the prior's rows
        join the constraints, weighted by the noise sigma, and the fit and sigma are iterated to their
        fixed point. None: plain least squares

    Returns
    -------
    SubspaceFit
    """
    R0 = residual(v0)
    m, d = R0.shape
    p = len(v0)
    w = np.ones(m) if w0 is None else np.asarray(w0, dtype=float).copy()
    if suspects is not None and robust:
        w[suspects] = 0.0
    sigma = prior.noise if prior is not None else 1.0
    n_con = 0 if constraints is None else len(constraints(v0)[0])
    lm = SubspaceLM(residual, jacobian, constraints, prior, robust, groups, suspects, m, d, p, sigma)
    con = [] if constraints is None else [constraints(v0)[1]]
    ident, _ = identifiability(np.vstack([jacobian(v0).reshape(m * d, p)] + con), names)  # data alone
    _, basis = identifiability(lm.jrows(v0, np.ones(m)), names)  # what data, constraints and prior fix
    sol, res, w, dof = lm.noise_fixed_point(v0, basis, w)
    return subspace_fit(lm, v0 + basis @ sol.x, basis, sol, res, w, ident, dof, n_con)


def subspace_fit(
    lm: SubspaceLM, v: np.ndarray, basis: np.ndarray, sol, res: np.ndarray, w: np.ndarray, ident, dof, n_con
) -> SubspaceFit:
    """The :class:`SubspaceFit` at the solution v (p,) in the subspace ``basis`` (p, r): without a prior
    the noise sigma^2 = |rows|^2 / (d m_used - r + c); the covariance B (A^T A)^-1 B^T sigma^2 of the
    weighted rows' Jacobian A in the subspace; each capture's leverage (the hat matrix's diagonal over
    its d rows). ``dof``: the prior's (eq. P3; None without a prior); ``n_con``: the constraint rows c.

    Raises
    ------
    IdentificationError : fewer usable residual rows than parameter combinations (without a prior)
    """
    m, d, p, r = lm.m, lm.d, lm.p, basis.shape[1]
    used = w > 0
    sw = np.sqrt(w)
    if lm.prior is None:
        dof = d * used.sum() - r + n_con
        if dof <= 0:
            raise IdentificationError(
                f"{used.sum()} usable captures cannot identify {r} parameter combinations"
            )
        lm.sigma = float(np.sqrt(np.sum(lm.rows(v, sw) ** 2) / dof))
    A = lm.jrows(v, sw) @ basis
    cov = basis @ covariance(A, lm.sigma) @ basis.T
    U, sv, _ = thin_svd(A)
    keep = sv > sv.max(initial=0.0) * 1e-12
    leverage = np.sum(U[: m * d, keep] ** 2, axis=1).reshape(m, d).sum(axis=1)
    rc, Jc = lm.constraints(v) if lm.constraints is not None else (np.zeros(0), np.zeros((0, p)))
    return SubspaceFit(
        v,
        cov,
        res,
        w,
        lm.sigma,
        ident,
        bool(sol.status > 0),
        lm.iterations,
        lm.history,
        lm.jacobian(v) @ basis,
        Jc @ basis,
        rc,
        lm.prior,
        float(dof),
        leverage,
    )
