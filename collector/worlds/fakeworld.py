"""What a real table, camera and arm add to the simulated world of the ``fake`` backend (issues 38, 45).

Each effect can be switched (``capture --effects``); a camera session (``--camera fake``) has them all on
by default, an aimed one none (the world the README's and docs' figures were measured in). The values
that vary from table to table are drawn once per session from its seed and stored in session.yaml
(``simulated.world``), so that ``validate`` sees the same world. The world is computed by its own code,
not by the functions the fit uses: the arm's beam (:mod:`collector.worlds.truearm`), the paper
(:mod:`collector.worlds.truesheet`), the lens (:mod:`collector.worlds.truelens`), the spot
(:mod:`collector.worlds.truespot`).

* ``repeatability``: the pose the arm reaches differs from what its encoders report, by Gaussian joint
  noise of :data:`REPEAT_SIGMA_RAD` per joint -- Franka's datasheet repeatability, ISO 9283's RP
  (mean + 3 std of the distance) of 0.1 mm, at the laser aperture over aiming poses at a sheet 450 mm
  out (about 0.06 mm RMS at the spot). A new draw for every pose reached.
* ``distortion``: the camera's lens distorts (radially, decentred, a thin prism: eq. L1); the session
  corrects it with the calibration ``lasercal camera-calibrate`` estimates from chessboard photos
  rendered through that lens (:func:`lens_estimate`, stored as ``simulated.world.lens``) -- not with the
  parameters that made the photos, which its model cannot even hold.
* ``occlusion``: the arm (capsules of :data:`ARM_RADIUS_MM` along its links) hides the spot from the
  camera when it lies on the line of sight.
* ``ellipse``: a beam meeting the sheet at a tilt lights an elliptic footprint, 1/cos(tilt) longer along
  its azimuth (eq. F1).
* ``subsurface``: the paper scatters part of the light under its skin and lets it out downstream: the
  spot's brightness is not symmetric about the beam's hit (eq. F2).
* ``print-scale``: the printer scales the sheet by a factor drawn uniformly within +-0.2 % along each of
  its axes: markers, crosses and all (the operator aims at the printed crosses).
* ``print-shear``: the paper runs through the printer a little askew: the print's y axis leans by a skew
  drawn within +-:data:`PRINT_SHEAR` (+-0.3 mm over an A4 sheet's 210 mm; eq. W1).
* ``sheet-height``: the sheet lies up to 0.5 mm above or below its stated plane (uniform draw).
* ``table-slope``: the table rises 1-4 mrad (:data:`TABLE_SLOPE`) in a direction drawn at random, in the
  true robot's frame (eq. W3).
* ``paper-curl``: the taped sheet bulges off the table along its middle by 0.1-0.3 mm
  (:data:`PAPER_BULGE_MM`, eq. W2): not a plane, which no model term holds.

Without ``occlusion`` the camera still sees the sheet from its stated pose (:func:`camera_pose`); without
``ellipse`` the footprint is round on the sheet (and perspective still makes it an ellipse in the photo).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from lasercal.collector.hardware.simulated import EFFECTS
from lasercal.collector.worlds.truelens import PRISM, RADIAL, TANGENTIAL, Lens, calibrated
from lasercal.collector.worlds.truesheet import PaperSheet

REPEAT_SIGMA_RAD = 4.7e-5  # per joint: RP 0.1 mm at the aperture (ISO 9283), see the module docstring
PRINT_SCALE = 0.002  # a printer scales each axis by up to +-0.2 %
PRINT_SHEAR = 1.5e-3  # and feeds the paper askew by up to this skew (mm per mm)
SHEET_HEIGHT_MM = 0.5  # the sheet lies up to 0.5 mm off its stated plane
TABLE_SLOPE = (1e-3, 4e-3)  # the table's rise, rad: a magnitude drawn within, in a direction drawn at random
PAPER_BULGE_MM = (0.1, 0.3)  # a taped sheet's bulge along its middle, mm
ARM_RADIUS_MM = 60.0  # the arm's links as capsules of this radius (a Panda's are 110-130 mm thick)
# The camera: 1280 x 960 px, 0.33 mm/px at the sheet's centre, 600 mm above the sheet and 350 mm beyond its
# centre on the side away from the robot (its x axis), looking at the centre: the arm reaches over the
# sheet from the other side, and the camera looks under it.
CAMERA_PX = (1280, 960)
CAMERA_MM_PER_PX = 0.33
CAMERA_OFFSET_MM = (350.0, 0.0, 600.0)
CALIBRATION_SEED = 0  # the fake camera is one device, calibrated once (as a user calibrates theirs)


@dataclass(frozen=True)
class World:
    """The effects of one simulated session and their drawn values.

    Attributes
    ----------
    effects : tuple of str, those switched on (:data:`EFFECTS`)
    print_scale : (2,) array, the printed sheet's scale along its x and y axes (1: exact)
    sheet_dz : float, the sheet's height above its stated plane, mm
    slope : (2,) array, the table's rise per mm along the sheet's x and y axes
    bulge : float, the paper's bulge off the table along its middle, mm
    shear : float, the print's skew (its y axis leans along x), mm per mm
    lens : vision.camera.Camera or None, the fake camera's calibration as a session recorded it (None: not
        recorded; :attr:`correction` estimates it when first needed)
    half_length : float, half the paper's length along the sheet's y axis, mm (where its bulge ends)
    """

    effects: tuple = ()
    print_scale: np.ndarray = field(default_factory=lambda: np.ones(2))
    sheet_dz: float = 0.0
    slope: np.ndarray = field(default_factory=lambda: np.zeros(2))
    bulge: float = 0.0
    shear: float = 0.0
    lens: object = None
    half_length: float = 148.5

    @classmethod
    def draw(cls, effects, seed: int, half_length: float = 148.5) -> World:
        """The world of a session with seed ``seed``: its table's draws (each keyed on its own), on a paper
        ``half_length`` mm long each side of its x axis (:func:`paper_half_length`)."""
        scale = np.ones(2)
        if "print-scale" in effects:
            scale = 1.0 + np.random.default_rng([seed, 0x9121]).uniform(-PRINT_SCALE, PRINT_SCALE, 2)
        dz = 0.0
        if "sheet-height" in effects:
            dz = float(np.random.default_rng([seed, 0x5EE7]).uniform(-SHEET_HEIGHT_MM, SHEET_HEIGHT_MM))
        slope = np.zeros(2)
        if "table-slope" in effects:
            rng = np.random.default_rng([seed, 0x5109])
            size, turn = rng.uniform(*TABLE_SLOPE), rng.uniform(0.0, 2 * np.pi)
            slope = size * np.array([np.cos(turn), np.sin(turn)])
        bulge = (
            float(np.random.default_rng([seed, 0xC081]).uniform(*PAPER_BULGE_MM))
            if "paper-curl" in effects
            else 0.0
        )
        shear = 0.0
        if "print-shear" in effects:
            shear = float(np.random.default_rng([seed, 0x54EA]).uniform(-PRINT_SHEAR, PRINT_SHEAR))
        return cls(
            tuple(e for e in EFFECTS if e in effects), scale, dz, slope, bulge, shear, None, half_length
        )

    @property
    def correction(self):
        """The lens correction a measurement applies (``distortion``): the calibration recorded, else
        ``camera-calibrate``'s estimate (:func:`lens_estimate`, computed when first needed: a session refused
        before its first photo does not wait for it); None without distortion."""
        if not self.has("distortion"):
            return None
        return self.lens if self.lens is not None else lens_estimate()

    @property
    def repeat_sigma(self) -> float:
        """Joint noise between the reached and the reported pose, rad (0: exact)."""
        return REPEAT_SIGMA_RAD if "repeatability" in self.effects else 0.0

    def has(self, effect: str) -> bool:
        return effect in self.effects

    def paper(self, placement, plane_z: float) -> PaperSheet:
        """The printed sheet as it truly lies (:class:`~collector.worlds.truesheet.PaperSheet`), the
        layout's origin placed at ``placement`` (x_mm, y_mm, yaw_deg: a SheetPose's numbers) on the plane
        ``plane_z`` (mm), its scale and slope ``placement``'s (a stated true pose's) with this world's on
        top."""
        own_scale = np.array([getattr(placement, "scale_x", 1.0), getattr(placement, "scale_y", 1.0)])
        own_slope = np.array([getattr(placement, "tilt_x_rad", 0.0), getattr(placement, "tilt_y_rad", 0.0)])
        return PaperSheet(
            np.array([placement.x_mm, placement.y_mm, plane_z + self.sheet_dz]),
            np.radians(placement.yaw_deg),
            own_scale * self.print_scale,
            self.shear,
            own_slope + self.slope,
            self.bulge,
            self.half_length,
        )

    def as_dict(self) -> dict:
        """What session.yaml stores (``simulated.world``)."""
        out = {
            "effects": list(self.effects),
            "print_scale": [float(s) for s in self.print_scale],
            "sheet_dz_mm": float(self.sheet_dz),
            "repeatability_rad": self.repeat_sigma,
            "table_slope_rad": [float(s) for s in self.slope],
            "paper_bulge_mm": float(self.bulge),
            "print_shear": float(self.shear),
            "paper_half_length_mm": float(self.half_length),
        }
        lens = self.correction
        if lens is not None:
            out["lens"] = {
                "K": [[float(v) for v in row] for row in lens.K],
                "dist": [float(v) for v in lens.dist],
                "rms_px": float(lens.rms_px),
                "from": "camera-calibrate on chessboard photos rendered through the fake camera's lens",
            }
        return out

    @classmethod
    def from_dict(cls, d) -> World:
        """The world session.yaml stored (None or missing: the clean world; a field missing: none of it)."""
        if not isinstance(d, dict):
            return cls()
        effects = tuple(e for e in EFFECTS if e in (d.get("effects") or ()))
        lens, rec = None, d.get("lens")
        if "distortion" in effects and isinstance(rec, dict):  # else estimated when first needed
            from lasercal.vision.camera import Camera

            K, dist = np.array(rec["K"], dtype=float), np.array(rec["dist"], dtype=float)
            lens = Camera(CAMERA_PX, K, dist, float(rec.get("rms_px", np.nan)))
        return cls(
            effects,
            np.asarray(d.get("print_scale", [1.0, 1.0]), dtype=float),
            float(d.get("sheet_dz_mm", 0)),
            np.asarray(d.get("table_slope_rad", [0.0, 0.0]), dtype=float),
            float(d.get("paper_bulge_mm", 0.0)),
            float(d.get("print_shear", 0.0)),
            lens,
            float(d.get("paper_half_length_mm", 148.5)),
        )


def camera_lens(world: World) -> Lens:
    """The fake camera's true lens: its focal length puts 0.33 mm/px at the sheet's centre; distorted
    (eq. L1) with ``distortion``."""
    w, h = CAMERA_PX
    f = np.linalg.norm(CAMERA_OFFSET_MM) / CAMERA_MM_PER_PX
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
    if not world.has("distortion"):
        return Lens(CAMERA_PX, K)
    return Lens(CAMERA_PX, K, RADIAL, TANGENTIAL, PRISM)


@lru_cache(maxsize=1)
def lens_estimate():
    """The fake camera's calibration: ``camera-calibrate``'s estimate from chessboard photos rendered through
    its true lens (:func:`collector.worlds.truelens.calibrated`; ~10 s, once per process)."""
    return calibrated(
        camera_lens(World(("distortion",))), float(np.linalg.norm(CAMERA_OFFSET_MM)), CALIBRATION_SEED
    )


def paper_half_length(layout) -> float:
    """Half the paper's length along the sheet's y axis, mm: the layout's ``paper`` (``lasercal sheet``'s:
    its width runs along y), else its points' reach plus 40 mm."""
    paper = (layout.raw or {}).get("paper") if hasattr(layout, "raw") else None
    if isinstance(paper, dict) and paper.get("width_mm"):
        return float(paper["width_mm"]) / 2
    return float(max(abs(p[1]) for p in layout.points.values()) + 40.0)


def camera_pose(centre: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """The fake camera's pose: R (base -> camera) and t (mm), ``x_cam = R x + t``.

    Parameters
    ----------
    centre : (3,) array, the sheet's centre in the base frame, mm
    yaw : float, the sheet's x axis from the base x axis, rad
    """
    c, s = np.cos(yaw), np.sin(yaw)
    off = np.asarray(CAMERA_OFFSET_MM)
    C = centre + np.array([c * off[0] - s * off[1], s * off[0] + c * off[1], off[2]])
    fwd = (centre - C) / np.linalg.norm(centre - C)
    right = np.cross(fwd, [0.0, 0.0, 1.0])  # the image's right: horizontal
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    R = np.vstack([right, down, fwd])
    return R, -R @ C


def hidden(capsules: np.ndarray, eye: np.ndarray, spot: np.ndarray, radius: float = ARM_RADIUS_MM) -> bool:
    """The line of sight from the camera ``eye`` to ``spot`` (mm) passes within ``radius`` of a link."""
    d = spot - eye
    for a, b in capsules:
        e = b - a
        # closest points of two segments (eye + s d, a + t e), s, t in [0, 1]
        A, B, C = d @ d, d @ e, e @ e
        r = eye - a
        D, E = d @ r, e @ r
        den = A * C - B * B
        s = np.clip((B * E - C * D) / den, 0, 1) if den > 1e-12 else 0.0
        t = np.clip((B * s + E) / C, 0, 1) if C > 1e-12 else 0.0
        s = np.clip((B * t - D) / A, 0, 1)
        if np.linalg.norm(eye + s * d - a - t * e) < radius:
            return True
    return False


def table_points(layout, world: World, beside=(0.0, 0.0)) -> dict:
    """Where the simulated operator aims: each point as printed, ``beside`` it (sheet mm; a camera session
    aims on white paper next to the cross), on the sheet's true surface, in the true robot's frame (a sheet
    at its placement), name -> (3,) mm.

    Parameters
    ----------
    layout : Layout, as loaded (a sheet's points in its own frame, with a placement)
    world : World
    beside : (2,) offset from each cross on the sheet, mm
    """
    names = list(layout.points)
    xy = np.array([layout.points[k][:2] for k in names]) + beside
    return dict(zip(names, on_table(layout, world, xy)))


def on_table(layout, world: World, xy: np.ndarray) -> np.ndarray:
    """Where spots of the layout's frame (k, 2) mm truly are: as printed, on the sheet's true surface
    (:meth:`World.paper`), in the true robot's frame (a sheet at its placement), (k, 3) mm."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if layout.frame != "sheet":
        return np.c_[xy, np.full(len(xy), layout.plane_z + world.sheet_dz)]
    return world.paper(layout.sheet, layout.plane_z).surface(xy)
