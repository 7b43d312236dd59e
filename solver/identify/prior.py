"""Priors from manufacturing tolerances: what a real arm's parameters may be before any data.

Robot calibration is least squares with priors: a real arm is its nominal model to within the
tolerances of its manufacture and assembly, and the data refine it where they can. Every
identification in ``solver`` (laser spots, tool points, 3-D positions, their extensions, the
capture coach) is the same maximum-a-posteriori (MAP) estimate:

* prior (eq. P1): T (x - x_0) ~ N(0, diag(s^2)), x_0 the nominal (the start), s from
  :class:`Tolerances` by parameter kind; s = inf is no prior (a sensor frame, identified points:
  anything goes). T is the identity but for each revolute joint's axis position, whose tolerance
  holds where the joint physically is (its bearings), not at its link frame's origin:
  T maps (qx, qy) to (qx + h wx, qy + h wy), h the joint's anchor height along its axis
  (:func:`~lasercal.solver.kinematics.minimal.anchor_heights`) -- a tilt of joint 5's axis about
  the elbow is not also a 10 mm offset;
* estimate (eq. P2): min_x |r(x)|^2 / sigma^2 + |T (x - x_0) / s|^2, solved by
  :func:`~lasercal.solver.identify.lsq.fit_subspace` with the prior as extra residual rows
  sigma T (x - x_0) / s (Levenberg-Marquardt in the identifiable subspace, robust loss);
* noise (eq. P3): log sigma^2 = (nu_0 log sigma_0^2 + nu log(RSS / nu)) / (nu_0 + nu), nu = d m - tr H
  the residual degrees of freedom (tr H = tr(J C J^T) / sigma^2, the effective number of fitted
  parameters): the precision-weighted mean, on the log scale where a variance's uncertainty is
  symmetric, of the measurement's nominal noise sigma_0 (weight nu_0, its pseudo-observations) and the
  data's own estimate RSS / nu (weight nu: the variance of log s^2 is 2 / nu). A session with few
  residual degrees of freedom keeps sigma near sigma_0 (the prior stabilises it); with many, sigma
  follows the data, and exact data (RSS -> 0) drive it to 0, so the geometry prior's weight sigma / s
  vanishes and the fit is exact. (A scaled-inverse-chi^2 posterior, (nu_0 sigma_0^2 + RSS) / (nu_0 + nu),
  adds sums of squares instead: 4 pseudo-observations at 1 mm outweighed 151 residual degrees of
  freedom at 0.017 mm and pulled an exact fit 0.08 mm towards the nominal.) P2 and P3 are iterated to
  their fixed point;
* covariance (eq. P4): C = (J^T J / sigma^2 + T^T diag(1 / s^2) T)^-1, through an SVD of the stacked
  rows (never a normal-matrix inverse); it has full rank wherever the prior is finite, and a
  direction the data cannot see keeps its prior variance;
* data or prior (eq. P5): the eigen-directions u of L C L^T, L = diag(1/s) T (the posterior in units
  of the prior) with eigenvalue lambda: sqrt(lambda) = posterior sigma / prior sigma along u.
  Near 1 the prior determined that combination, near 0 the data did.

``--prior none`` (``prior=None`` everywhere) is plain least squares: the thesis's comparisons keep it.

The tolerances s, their defaults and their files are :mod:`solver.formats.tolerances`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.formats.tolerances import Tolerances


@dataclass(frozen=True)
class Prior:
    """A Gaussian prior on one parameter vector (eq. P1) and on the noise (eq. P3).

    Attributes
    ----------
    mean : (p,) array, x_0
    std : (p,) array, s (inf: no prior on that parameter)
    noise : float, sigma_0, mm
    noise_dof : float, nu_0
    T : (p, p) array, the map whose image has the independent tolerances s (eq. P1; invertible)
    """

    mean: np.ndarray
    std: np.ndarray
    noise: float
    noise_dof: float
    T: np.ndarray

    @property
    def finite(self) -> np.ndarray:
        """(p,) bool: rows of T (x - x_0) with a prior."""
        return np.isfinite(self.std)

    @property
    def whitening(self) -> np.ndarray:
        """L = diag(1/s) T over the finite rows (k, p): L (x - x_0) ~ N(0, I) (eqs. P1, P5)."""
        f = self.finite
        return self.T[f] / self.std[f, None]

    def rows(self, v: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
        """The prior's residual rows sigma L (v - x_0) and their Jacobian sigma L (eq. P2)."""
        L = sigma * self.whitening
        return L @ (v - self.mean), L


def noise_sigma(sigma_0: float, nu_0: float, rss: float, nu: float) -> float:
    """The noise sigma of eq. P3 (mm): sigma_0 weighted by nu_0 and sqrt(RSS / nu) by nu, on the log scale.

    Parameters
    ----------
    sigma_0 : float, the measurement's nominal noise, mm
    nu_0 : float, its pseudo-observations
    rss : float, residual sum of squares of the used captures, mm^2
    nu : float, residual degrees of freedom d m - tr H (<= 0: the prior alone)

    Returns
    -------
    float, mm; at least 1e-9 sigma_0 (exact data: the fit is exact to round-off well before)
    """
    if nu <= 0:
        return sigma_0
    log_var = (nu_0 * np.log(sigma_0**2) + nu * np.log(max(rss / nu, 1e-300))) / (nu_0 + nu)
    return float(max(np.exp(0.5 * log_var), 1e-9 * sigma_0))


def make_prior(
    tol: Tolerances | None,
    kinds,
    mean: np.ndarray,
    measurement: str,
    names: list | None = None,
    joint_names=(),
    heights: np.ndarray | None = None,
) -> Prior | None:
    """The prior of a parameter vector of the given kinds about ``mean`` (None: plain least squares).

    Parameters
    ----------
    tol : Tolerances or None
    kinds : list of p str, keys of :data:`KINDS`
    mean : (p,) array, x_0
    measurement : str, 'laser', 'point' or 'position' (sigma_0)
    names, joint_names, heights : the parameter names ('joint4.qx', ...), the joints' names and their
        anchor heights (mm, :func:`~lasercal.solver.kinematics.minimal.anchor_heights`): the axis
        position's tolerance then holds at the joint (eq. P1's T); without them, T = I
    """
    if tol is None:
        return None
    p = len(kinds)
    T = np.eye(p)
    if names is not None and heights is not None:
        idx = {nm: i for i, nm in enumerate(names)}
        for jn, h in zip(joint_names, heights):
            for qc, wc in (("qx", "wx"), ("qy", "wy")):
                if f"{jn}.{qc}" in idx and f"{jn}.{wc}" in idx:
                    T[idx[f"{jn}.{qc}"], idx[f"{jn}.{wc}"]] = h
    return Prior(np.asarray(mean, float).copy(), tol.std(kinds), tol.noise(measurement), tol.noise_dof, T)
