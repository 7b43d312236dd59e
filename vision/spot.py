"""The measured laser spot: its centre (px), uncertainty, position on the plane (mm), and the evidence
that it is laser light."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

CHANNEL = {"red": 2, "green": 1}  # BGR index of each laser's colour


@dataclass(frozen=True)
class Evidence:
    """What a candidate spot looks like, and so why it was accepted or rejected.

    Attributes
    ----------
    colour : "red", "green", or None for a grey photo
    excess : float, peak of the laser's channel over the local paper level, fraction of full scale
    snr : float, that excess over the paper's noise in the same channel
    level : float, highest value of the laser's channel in the spot, fraction of full scale
    light : float, peak excess of the luma over the local paper level, fraction of full scale: laser
        light adds light, while red ink, whose red a phone's colour correction lifts above the
        paper's, takes it away
    halo_ratio : float or None, colour of the spot's halo in the photo's own encoding: the laser
        channel's excess over the brighter other channel's, summed over the spot's pixels not clipped
        in all three channels (capped at 20); None for a grey photo. Descriptive only: the rim shift
        decides
    clipped_px : int, spot pixels clipped in the laser's channel
    white_px : int, spot pixels (nearly) clipped in all three channels, >= 97 % of full scale (a white core)
    area : int, pixels in the spot's blob
    confidence : float in [0, 1], the probability that the candidate is laser light, from its rim
        shift against the threshold of its rule (a logistic model fitted on labelled candidates, see
        :mod:`vision.decide`; 0 until judged)
    rim_ratio : float or None, the light the candidate adds in the laser's channel over what it adds
        in another channel, summed over its rim, in linear light (capped at 20)
    paper_ratio : float or None, the same ratio of the paper's own light under that rim
    rim_shift : float or None, ``rim_ratio / max(1, paper_ratio)`` against the laser's neighbours in
        wavelength (red: green; green: red and blue, both shifted by at least 1.2): <= 1 for white
        light on any paper in theory; the threshold a spot needs is its rule's (:mod:`vision.decide`)
    rule : str or None, which rule took the candidate for laser light: "rim" (its rim shifts towards
        the laser's hue), "core" (a compact clipped white core with a laser-ward fringe: a spot
        exposed far past clipping), "view" (a clipped core in a surround of nearly monochromatic
        laser light: the spot's own halo fills the view), "ring" (a white core of any size inside a
        ring of the laser's colour, see :mod:`vision.ring`), "grey" (a grey photo: brightness only);
        None when none did
    flux : float, light the spot adds in the laser's channel, summed over its blob, linear, DN px
        (of the full photo); one laser adds about the same wherever it lands
    cut : bool, the photo's edge cuts the spot
    surround : float or None, the laser channel over the brighter other one in the box's surround
        (linear): >= 20 only where the laser's own halo fills the view
    lit : float, how far the spot clears the brightness it needs: the smaller of log(excess / need)
        and log(luma rise / its need)
    ring : float or None, DN (8-bit scale): for a white clipped core, how laser-coloured the ring
        around it is, in its second-weakest angular sector (see :mod:`vision.ring`); None when the
        candidate has no core of that size
    side : float or None, how one-sided the laser-coloured light around the spot is: 0 when it is
        centred on the spot (a laser's own halo), 1 when it is all on one side (a disc or a glint in
        another spot's halo, a lamp whose red light an edge cuts); see ``features._laser_light``
    share : float, the share of the photo the spot's blob covers
    reach : float, px, how far the spot's laser-coloured light (its halo) reaches from its centre
    rim_centre : (u, v) px or None, the centre of the spot's clipped core from the rim of its
        saturation (:func:`vision.bare.rim_centre`), in the photo; None when it has no clipped core of
        :data:`~vision.bare.RIM_MIN_PX` px
    bare : int or None, for a white clipped blob: how many compact white clipped blobs of a laser
        core's size the photo holds (:mod:`vision.bare`; 1: this one alone); None when not counted
    lopsided : float or None, how far the spot's light is from point-symmetric about its centre
        (:func:`vision.bare.lopsided`: 0 a beam's, up to 1 a glow an edge cuts); None when not measured
    """

    colour: str | None
    excess: float
    snr: float
    level: float
    light: float
    halo_ratio: float | None
    clipped_px: int
    white_px: int
    area: int
    confidence: float
    rim_ratio: float | None = None
    paper_ratio: float | None = None
    rim_shift: float | None = None
    rule: str | None = None
    flux: float = 0.0
    cut: bool = False
    surround: float | None = None
    lit: float = 0.0
    ring: float | None = None
    side: float | None = None
    share: float = 0.0
    reach: float = 0.0
    rim_centre: tuple | None = None
    bare: int | None = None
    lopsided: float | None = None

    @property
    def strength(self) -> float:
        """How convincing the spot is against other spots of the same photo: its flux times its
        confidence, and a quarter of that when the photo's edge cuts it (its centre is extrapolated,
        and it may be an object running out of view)."""
        return self.flux * self.confidence * (0.25 if self.cut else 1.0)

    @property
    def clipped_fraction(self) -> float:
        """Fraction of the spot's pixels clipped in the laser's channel."""
        return self.clipped_px / max(self.area, 1)

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return {
            "colour": self.colour,
            "excess": round(self.excess, 4),
            "snr": round(self.snr, 1),
            "level": round(self.level, 4),
            "light": round(self.light, 4),
            "halo_ratio": None if self.halo_ratio is None else round(self.halo_ratio, 2),
            "clipped_px": self.clipped_px,
            "white_px": self.white_px,
            "clipped_fraction": round(self.clipped_fraction, 3),
            "confidence": round(self.confidence, 3),
            "rim_ratio": None if self.rim_ratio is None else round(self.rim_ratio, 2),
            "paper_ratio": None if self.paper_ratio is None else round(self.paper_ratio, 3),
            "rim_shift": None if self.rim_shift is None else round(self.rim_shift, 2),
            "rule": self.rule,
            "flux": round(self.flux, 1),
            "cut": self.cut,
            "surround": None if self.surround is None else round(self.surround, 2),
            "lit": round(self.lit, 3),
            "ring": None if self.ring is None else round(self.ring, 1),
            "side": None if self.side is None else round(self.side, 3),
            "share": round(self.share, 6),
            "reach": round(self.reach, 1),
            "bare": self.bare,
            "lopsided": None if self.lopsided is None else round(self.lopsided, 3),
        }

    def describe(self) -> str:
        """One line of the evidence, for messages."""
        rim = "" if self.rim_shift is None else f"rim shift {self.rim_shift:.2f}, "
        rule = "" if self.rule is None else f"rule {self.rule}, "
        return (
            f"{rule}{rim}excess {self.excess:.2f} of full scale ({self.snr:.0f} sigma), "
            f"luma {self.light:+.2f}, {self.clipped_px} px clipped, confidence {self.confidence:.2f}"
        )


class Pending:
    """The slow part of measuring a spot, its precise centre (a profile fit), put off until a rule takes
    the spot for laser light (most candidates are not), then computed once (``vision.decide.finish``).

    Parameters
    ----------
    run : callable () -> (u, v, sigma_u, sigma_v) px in the image measured, or the key of the gate that
        refuses the spot once fitted (``vision.decide.REASONS``)
    scale : int, the image measured is the photo shrunk by this factor (a spot hundreds of px wide)
    fallback : Spot or None, reported instead when the fit refuses the spot (a ringed core's own spot)
    """

    def __init__(self, run, scale: int = 1, fallback: Spot | None = None):
        self._run, self.scale, self.fallback, self._out = run, scale, fallback, None

    def result(self):
        """``run()``'s result, computed on the first call only."""
        if self._out is None:
            self._out = self._run()
        return self._out


@dataclass(frozen=True)
class Spot:
    """One measured laser spot.

    Attributes
    ----------
    u, v : float, centre, px (OpenCV convention)
    sigma_u, sigma_v : float or None, 1-sigma uncertainty of the centre, px
        (None for the ``imagej`` method, which has no error model)
    peak : float, highest value of the laser's channel in the spot, DN
    saturated : bool, some of the spot's pixels are clipped at full scale
    area : int, pixels in the spot's blob
    x_mm, y_mm : float or None, position on the table plane, base frame, mm
    sigma_x_mm, sigma_y_mm : float or None, the centre's uncertainty mapped to mm
    on_ink : bool, printed ink (a mark) lies under the spot: it swallows laser light
        unevenly and may bias the centre by a few tenths of a pixel
    evidence : Evidence or None, why the spot was taken for laser light (None for ``imagej``)
    """

    u: float
    v: float
    sigma_u: float | None
    sigma_v: float | None
    peak: float
    saturated: bool
    area: int
    x_mm: float | None = None
    y_mm: float | None = None
    sigma_x_mm: float | None = None
    sigma_y_mm: float | None = None
    on_ink: bool = False
    evidence: Evidence | None = None
    pending: Pending | None = field(default=None, repr=False, compare=False)

    def to_dict(self, convention: str = "opencv") -> dict:
        """JSON-ready dict; ``convention="imagej"`` adds 0.5 px to u and v."""
        shift = 0.5 if convention == "imagej" else 0.0

        def r(x, n):
            return None if x is None else round(float(x), n)

        return {
            "u": r(self.u + shift, 4),
            "v": r(self.v + shift, 4),
            "sigma_u": r(self.sigma_u, 4),
            "sigma_v": r(self.sigma_v, 4),
            "x_mm": r(self.x_mm, 4),
            "y_mm": r(self.y_mm, 4),
            "sigma_x_mm": r(self.sigma_x_mm, 4),
            "sigma_y_mm": r(self.sigma_y_mm, 4),
            "peak": r(self.peak, 1),
            "saturated": bool(self.saturated),
            "area": int(self.area),
            "on_ink": bool(self.on_ink),
            "evidence": None if self.evidence is None else self.evidence.to_dict(),
        }


def with_plane(spot: Spot, x: float, y: float, sx: float | None, sy: float | None) -> Spot:
    """The spot with its plane position (mm) filled in."""
    return replace(spot, x_mm=x, y_mm=y, sigma_x_mm=sx, sigma_y_mm=sy)
