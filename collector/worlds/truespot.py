"""The fake world's laser spot on paper: the beam's footprint and the light the paper scatters under its
skin, as ``vision.render`` laser spots seen through a view (issue 45).

* The footprint: a beam of Gaussian cross-section (sigma s at the paper) lights the paper where a point's
  distance from the beam's axis is small: a printed offset du (2,) mm from the hit moves the point by
  T du in space (T = d surface / d(u, v), 3 x 2), whose distance from the axis (unit d) is |(I - d d^T) T
  du|. The irradiance exp(-|.|^2 / (2 s^2)) is a Gaussian in du of covariance (eq. F1)

      C = s^2 (T^T (I - d d^T) T)^-1

  -- 1/cos(incidence) longer along the beam's azimuth on a flat sheet; without ``ellipse`` it is round on
  the paper, C = s^2 (T^T T)^-1.
* Subsurface light (``subsurface``): paper is a scattering medium. A fraction f of the light enters it,
  runs along the refracted ray (sin r = sin i / n_paper) to a depth ~d_s, and comes out around a point
  d_s tan r downstream along the beam's azimuth, spread by w_s (eq. F2). The spot is then the footprint
  plus a weaker, wider glow shifted downstream: its brightness is not symmetric about the beam's hit, and a
  centroid reads the spot ~f d_s tan r downstream (0.01-0.03 mm at 20-50 deg incidence) -- a bias of the
  paper, which no model term holds.

Both are mapped to pixels through the view's local Jacobian at the hit (the footprint spans a few mm, over
which the view is affine to a few 1e-4).
"""

from __future__ import annotations

import numpy as np

BEAM_SIGMA_MM = 1.0  # the footprint's sigma on the sheet at normal incidence, mm
SPOT_PEAK = 0.3  # the spot's peak at normal incidence, of full scale: exposed not to clip on the paper
SPECKLE = 0.2  # the footprint's speckle contrast (the glow's averages out over the paper's depth)
GLOW_FRACTION = 0.25  # f: of the spot's light, what the paper scatters under its skin
SCATTER_DEPTH_MM = 0.2  # d_s: how deep the light runs before it turns back, mm
GLOW_WIDTH_MM = 0.6  # w_s: how far it spreads, mm
PAPER_INDEX = 1.5  # n_paper: cellulose


def footprint(view, paper, uv: np.ndarray, d: np.ndarray, ellipse: bool, subsurface: bool, gain: float = 1.0):
    """The laser spots (one or two ``vision.render.LaserSpot``) of a beam of unit direction d (3,) hitting
    the paper at printed uv (2,) mm, in the pixels of ``view`` (``project``: printed mm -> px).

    Parameters
    ----------
    view : object with ``project(uv (k, 2)) -> (k, 2) px``
    paper : :class:`~collector.worlds.truesheet.PaperSheet` (``tangents``, ``normal``)
    uv : (2,) array, the beam's hit in the layout's printed coordinates, mm
    d : (3,) array, the beam's unit direction
    ellipse, subsurface : bool, the effects on (eqs. F1, F2)
    gain : float, the camera's exposure gain on the light

    Returns
    -------
    tuple of LaserSpot: the footprint (and the glow with ``subsurface``)
    """
    from lasercal.vision.render import LaserSpot

    uv = np.asarray(uv, dtype=float)
    T = paper.tangents(uv[None])[0]  # (3, 2)
    metric = T.T @ T
    across = T.T @ (np.eye(3) - np.outer(d, d)) @ T if ellipse else metric
    cov = BEAM_SIGMA_MM**2 * np.linalg.inv(across)  # eq. F1, printed mm^2
    h = 0.01
    J = np.column_stack([(view.project(uv + e) - view.project(uv - e))[0] / (2 * h) for e in np.eye(2) * h])
    centre = view.project(uv[None])[0]
    # the irradiance: the beam's power over its footprint's area on the paper
    peak = gain * SPOT_PEAK * BEAM_SIGMA_MM**2 / np.sqrt(np.linalg.det(cov) * np.linalg.det(metric))
    if not subsurface:
        return (_spot(LaserSpot, centre, J @ cov @ J.T, peak, SPECKLE),)
    n = paper.normal(uv[None])[0]
    cos_i = min(abs(float(d @ n)), 1.0)
    sin_r = np.sqrt(1 - cos_i**2) / PAPER_INDEX
    along = d - (d @ n) * n
    shift3 = np.zeros(3)
    if np.linalg.norm(along) > 1e-12:
        shift3 = SCATTER_DEPTH_MM * sin_r / np.sqrt(1 - sin_r**2) * along / np.linalg.norm(along)
    shift = np.linalg.solve(metric, T.T @ shift3)  # printed mm, eq. F2
    glow = cov + GLOW_WIDTH_MM**2 * np.linalg.inv(metric)
    C_core, C_glow = J @ cov @ J.T, J @ glow @ J.T
    # the glow carries a fraction f of the light: its peak is the core's scaled by the areas
    glow_peak = peak * GLOW_FRACTION * np.sqrt(np.linalg.det(C_core) / np.linalg.det(C_glow))
    core = _spot(LaserSpot, centre, C_core, peak * (1 - GLOW_FRACTION), SPECKLE)
    return core, _spot(LaserSpot, centre + J @ shift, C_glow, glow_peak, 0.0)


def _spot(LaserSpot, centre: np.ndarray, C: np.ndarray, peak: float, speckle: float):
    """A LaserSpot of pixel covariance C (2, 2) at ``centre`` (2,) px."""
    val, vec = np.linalg.eigh(C)
    major = np.sqrt(val[1])
    angle = np.degrees(np.arctan2(vec[1, 1], vec[0, 1]))
    return LaserSpot(
        centre[0], centre[1], major, peak, speckle, aspect=np.sqrt(val[0]) / major, angle_deg=angle
    )
