"""Synthetic phone photos of large clipped laser spots beside grey discs, with known truth (issue 41).

A phone photo of an A4 sheet at 12 MP has ~0.1 mm per pixel: a 2-3 mm laser spot is 10-15 px in
radius, and at any exposure that shows the sheet it clips. What phones record then (measured on the
shared real photos, see docs/vision.md "Large clipped spots"): a white core (every channel clipped,
or desaturated by the phone's highlight processing once the laser's channel nears clipping) inside a
thin ring of the laser's colour, with a broad, fainter halo of light the surface scatters under its
skin. The core grows with the exposure; the ring narrows and turns pale (pink or orange for red,
pale green for green).

:func:`clipped_scene` draws one such photo: the beam's sigma is chosen so that the laser's channel
clips out to the asked core radius, the cross-talk of the other channels, the scatter wing, the
highlight desaturation and the chroma noise reduction vary from photo to photo, and a grey disc (a
printed dot) lies beside the spot, as does a clipped white glint. Pixels in OpenCV's convention.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.vision.render import (
    Glare,
    LaserSpot,
    PhoneCamera,
    Photo,
    ink_dot,
    look_down,
    render,
    tilted_spot,
)

SIZE = (640, 480)  # px: a crop of a 12-megapixel photo around the spot
MM_PER_PX = 0.1
PAPERS = {  # reflectance (B, G, R) of the surface, and its level under the room light
    "white": ((1.0, 1.0, 1.0), 0.75),
    "grey": ((1.0, 1.0, 1.0), 0.35),
    "yellow": ((0.25, 0.9, 0.95), 0.75),
    "dark": ((1.0, 1.0, 1.0), 0.08),
}


@dataclass(frozen=True)
class ClippedScene:
    """One rendered photo and its truth.

    Attributes
    ----------
    img : (h, w, 3) uint8 BGR photo
    truth : (2,) float, the spot's true centre, px
    discs : (k, 2) float, the centres of the grey discs and white glints beside it, px
    core_px : int, pixels of the spot's white core as recorded (all channels >= 247)
    """

    img: np.ndarray
    truth: np.ndarray
    discs: np.ndarray
    core_px: int


def clipped_scene(
    seed: int, colour: str, core_radius: float, exposure: float, paper: str, laser: bool = True
) -> ClippedScene:
    """Render a large clipped spot with a grey disc and a white glint beside it.

    Parameters
    ----------
    seed : int, all random choices (position, tilt, cross-talk, scatter, processing, noise)
    colour : "red" or "green"
    core_radius : float, px, radius out to which the laser's channel clips (the white core's, give or
        take the phone's processing)
    exposure : float (> 1), the beam's peak light over the clipping level
    paper : a key of :data:`PAPERS`
    laser : bool, False draws the same scene with the laser off (the disc and the glint only)

    Returns
    -------
    ClippedScene
    """
    rng = np.random.default_rng([seed, int(100 * core_radius), int(100 * exposure)])
    view = look_down(SIZE, MM_PER_PX, centre=(450.0, 0.0))
    refl, level = PAPERS[paper]
    w, h = SIZE
    uv = np.array([w / 2, h / 2]) + rng.uniform(-30, 30, 2)
    tilt = rng.uniform(0, 40)
    scatter, width = rng.uniform(0.01, 0.05), rng.uniform(3, 5)
    spot = clipped_spot(
        uv, core_radius, exposure, tilt, rng.uniform(0, 180), rng.uniform(0.1, 0.3), scatter, width
    )
    reach = core_radius / np.cos(np.radians(tilt))  # the clipped plateau's semi-major axis
    # A grey disc (printed dot) ~110 px away, brighter than a dark wall and darker than white paper,
    # and a white glint (a clipped reflection) on the other side.
    ang = rng.uniform(0, 2 * np.pi)
    disc_uv = uv + (110 + reach) * np.array([np.cos(ang), np.sin(ang)])
    glint_uv = uv - (120 + reach) * np.array([np.cos(ang), np.sin(ang)])
    grey = 3.5 if paper == "dark" else 0.55
    disc_d = rng.uniform(1.0, 2.0) * core_radius * MM_PER_PX * 2
    prints = (ink_dot(view.unproject(disc_uv[None])[0], disc_d, (grey,) * 3),)
    glare = Glare(*glint_uv, sigma=max(core_radius / 2, 2.0), peak=rng.uniform(3, 30))
    leak = rng.uniform(0.04, 0.15)  # the other channels' response to the laser (Bayer filters' cross-talk)
    # Blue: some sensors pass a red laser to blue as much as to green or more (a pink or magenta ring).
    response = (rng.uniform(0.03, 0.3), leak, 1.0) if colour == "red" else (leak, 1.0, rng.uniform(0.02, 0.1))
    camera = PhoneCamera(
        bloom=rng.uniform(0.2, 0.6),
        jpeg=int(rng.integers(80, 95)),
        ae_target=None,
        ae_stops=0.0,
        highlight=rng.uniform(0.0, 0.9),
        chroma_blur=rng.uniform(0.0, 2.0),
    )
    photo = Photo(
        view,
        prints=prints,
        spots=(spot,) if laser else (),
        glares=(glare,),
        colour=colour,
        paper=level,
        tint=(rng.uniform(0.8, 1.0), rng.uniform(0.92, 1.0), 1.0),
        camera=camera,
        response=response,
        surface=refl,
    )
    img = render(photo, seed)
    core = (img >= 247).all(axis=2)
    yy, xx = np.mgrid[:h, :w]
    own = core & (np.hypot(xx - uv[0], yy - uv[1]) <= 1.5 * reach + 3)
    return ClippedScene(img, uv, np.array([disc_uv, glint_uv]), int(own.sum()))


def clipped_spot(
    uv,
    core_radius: float,
    exposure: float,
    tilt: float,
    azimuth: float,
    speckle: float,
    scatter: float,
    width: float,
) -> LaserSpot:
    """A beam whose laser channel clips out to ``core_radius`` px along the minor axis, ``exposure``
    times the clipping level at its peak, tilted ``tilt`` deg towards ``azimuth`` deg, with a scatter
    wing of ``scatter`` of the peak ``width`` times wider: its sigma from the profile
    E (g(x) + scatter g(x / width)) = 1 at x = core_radius / sigma (g: unit Gaussian)."""
    x = _clip_radius(exposure, scatter, width)
    return tilted_spot(
        *uv,
        max(core_radius / x, 1.0),
        exposure / np.cos(np.radians(tilt)),
        tilt,
        azimuth,
        speckle=speckle,
        scatter=scatter,
        scatter_width=width,
    )


def _clip_radius(exposure: float, scatter: float, width: float) -> float:
    """x > 0 where exposure (exp(-x**2 / 2) + scatter exp(-x**2 / (2 width**2))) = 1, in beam sigmas
    (bisection: the profile falls monotonically); 1 when the peak does not clip."""

    def light(x):
        return exposure * (np.exp(-0.5 * x * x) + scatter * np.exp(-0.5 * (x / width) ** 2))

    if light(0.0) <= 1:
        return 1.0
    lo, hi = 0.0, 10.0 * width
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if light(mid) > 1 else (lo, mid)
    return 0.5 * (lo + hi)
