"""The measured laser spot: its centre (px), uncertainty, and position on the plane (mm)."""

from __future__ import annotations

from dataclasses import dataclass, replace

CHANNEL = {"red": 2, "green": 1}  # BGR index of each laser's colour


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
        }


def with_plane(spot: Spot, x: float, y: float, sx: float | None, sy: float | None) -> Spot:
    """The spot with its plane position (mm) filled in."""
    return replace(spot, x_mm=x, y_mm=y, sigma_x_mm=sx, sigma_y_mm=sy)
