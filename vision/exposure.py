"""Exposure advice: is a photo a good measurement of its laser spot, and if not, what to change.

A laser spot on paper is measured best when it is bright against the paper but clipped
over few pixels. Clipping hides the spot's profile (only the plateau's edge and the flanks
are left to measure) and blooming spreads it; a faint spot drowns in noise and speckle.
The numbers come from the spots' :class:`~vision.spot.Evidence`; units as there
(fractions of full scale, pixels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.vision.spot import Spot

CLIPPED_MAX = 40  # px: a spot clipped over more pixels than this is a poor measurement
FAINT_EXCESS = 0.2  # fraction of full scale: an unclipped spot fainter is noise-limited (~0.1 px and worse)
GAMMA = 2.2  # a camera JPEG's encoding
PX_PER_STOP = 4.4 * 2.5**2  # px: a Gaussian spot's clipped area shrinks by 2 pi ln2 sigma**2 per stop


@dataclass(frozen=True)
class Exposure:
    """How well exposed a photo's spot is.

    Attributes
    ----------
    clipped_px : int, pixels of the spot clipped in the laser's channel (the most clipped spot)
    clipped_fraction : float, those over the spot's area
    white_px : int, pixels of its white core (clipped in all channels)
    contrast : float, excess of the laser's channel over the paper, fraction of full scale (the
        faintest spot)
    snr : float, that excess over the paper's noise
    stops : float, suggested exposure change, stops (negative: darker; 0: leave it)
    advice : str or None, one line for the operator when the photo is a poor measurement
    """

    clipped_px: int
    clipped_fraction: float
    white_px: int
    contrast: float
    snr: float
    stops: float
    advice: str | None

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return {
            "clipped_px": self.clipped_px,
            "clipped_fraction": round(self.clipped_fraction, 3),
            "white_px": self.white_px,
            "contrast": round(self.contrast, 4),
            "snr": round(self.snr, 1),
            "stops": self.stops,
            "advice": self.advice,
        }


def exposure_advice(spots: list[Spot], reference: bool = False) -> Exposure | None:
    """Clipping and contrast of a photo's spots, and one line of advice when they make a poor measurement.

    Parameters
    ----------
    spots : list of Spot from the precise method (with ``evidence``)
    reference : bool, the photo was measured against a laser-off reference (then not suggested)

    Returns
    -------
    Exposure, or None when no spot carries evidence (none found, or the ``imagej`` method)

    Notes
    -----
    The stops to lower a clipped spot by are a rule of thumb: a Gaussian spot's clipped area
    shrinks by 2 pi ln(2) sigma**2 per stop, ~28 px for the sigma ~2.5 px of a laser pointer's
    spot at ~0.3 mm/px (blooming adds to it). The stops to raise a faint one bring its peak
    to about 90 % of full scale, assuming a 2.2 gamma.
    """
    ev = [s for s in spots if s.evidence is not None]
    if not ev:
        return None
    worst = max(ev, key=lambda s: s.evidence.clipped_px)
    faint = min(ev, key=lambda s: s.evidence.excess)
    e, f = worst.evidence, faint.evidence
    tail = "" if reference else ", or turn on the laser-off reference"
    stops, advice = 0.0, None
    if e.clipped_px > CLIPPED_MAX:
        stops = -float(np.clip(np.ceil(e.clipped_px / PX_PER_STOP), 1, 4))
        advice = (
            f"spot clipped over {e.clipped_px} px: lower the exposure by about {-stops:.0f} "
            f"stop{'s' * (stops < -1)}{tail}"
        )
    elif not faint.saturated and f.excess < FAINT_EXCESS:
        # Raise until the spot's peak nears full scale (linear light scales with the exposure).
        stops = float(np.clip(np.round(2 * GAMMA * np.log2(0.9 / max(f.level, 0.01))) / 2, 0, 4))
        what = f"raise the exposure by about {stops:g} stop{'s' * (stops > 1)}, " if stops >= 0.5 else ""
        advice = (
            f"spot faint ({f.excess:.2f} of full scale over the paper, {f.snr:.0f} sigma): {what}"
            f"dim the room light{tail}"
        )
    return Exposure(e.clipped_px, e.clipped_fraction, e.white_px, f.excess, f.snr, stops, advice)
