"""Laser alignment check (thesis step (i)): spots while only joint 7 turns.

If the beam meets the joint-7 axis at a distance ``L`` (the laser length, mm) above
the plane and is tilted from it by ``alpha``, turning joint 7 moves the spot on a
circle of radius ``L tan(alpha)`` about the axis' intersection with the plane (the
circle-point idea of the Sensors 2013 seed, in the plane). A beam that misses the
axis by ``d`` adds to the radius (``r^2 ~ d^2 + (L tan alpha)^2``): one plane height
cannot tell the two apart, so the tilt reported is an upper bound.

Units: pixels (OpenCV convention) or mm on the plane; tilt in mrad and degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from lasercal.vision.errors import CalibrationError


@dataclass(frozen=True)
class Circle:
    """A circle fitted to points.

    Attributes
    ----------
    centre : (2,) array, same units as the points
    radius : float
    radius_sigma : float, 1-sigma of the radius from the fit's residuals (nan for 3 points)
    rms : float, RMS of the radial residuals
    arc_deg : float, angle the points span about the centre, degrees
    residuals : (n,) array, signed radial residuals
    """

    centre: np.ndarray
    radius: float
    radius_sigma: float
    rms: float
    arc_deg: float
    residuals: np.ndarray


def fit_circle(points: np.ndarray) -> Circle:
    """Geometric least-squares circle (algebraic Kasa fit as the start).

    Parameters
    ----------
    points : (n, 2) array, n >= 3

    Raises
    ------
    CalibrationError
        Fewer than 3 points, or points on a line.
    """
    p = np.asarray(points, float).reshape(-1, 2)
    if len(p) < 3:
        raise CalibrationError(f"a circle needs at least 3 spots, got {len(p)}")
    m = p.mean(0)
    q = p - m  # centring keeps the normal equations well conditioned
    scale = np.abs(q).max()
    if scale == 0:
        raise CalibrationError(
            "all spots are at the same place: the beam is aligned with the axis "
            "to within the measurement (radius 0)"
        )
    q = q / scale
    sv = np.linalg.svd(q, compute_uv=False)
    if sv[1] < 1e-6 * sv[0]:
        raise CalibrationError("the spots lie on a line, not on a circle")
    A = np.column_stack([q, np.ones(len(q))])
    sol, *_ = np.linalg.lstsq(A, (q**2).sum(1), rcond=None)
    c0 = sol[:2] / 2
    r0 = np.sqrt(max(sol[2] + c0 @ c0, 1e-12))
    if r0 > 1e3:
        raise CalibrationError("the spots lie on a line, not on a circle")
    res = least_squares(lambda x: np.hypot(*(q - x[:2]).T) - x[2], np.r_[c0, r0], method="lm")
    c, r = res.x[:2], abs(res.x[2])
    resid = res.fun * scale
    dof = len(p) - 3
    sigma = float("nan")
    if dof > 0:
        cov = np.linalg.pinv(res.jac.T @ res.jac) * (resid @ resid / dof)
        sigma = float(np.sqrt(cov[2, 2]) * scale)
    ang = np.sort(np.arctan2(*(q - c).T[::-1]))
    gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
    return Circle(
        m + c * scale,
        float(r * scale),
        sigma,
        float(np.sqrt(np.mean(resid**2))),
        float(np.degrees(2 * np.pi - gaps.max())),
        resid,
    )


def tilt(radius_mm: float, laser_length_mm: float) -> float:
    """Beam tilt from the joint-7 axis, rad, from the circle radius and the laser length (mm)."""
    if laser_length_mm <= 0:
        raise CalibrationError(f"--laser-length must be positive, got {laser_length_mm} mm")
    return float(np.arctan2(radius_mm, laser_length_mm))
