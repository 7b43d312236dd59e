"""What a real table, camera and arm add to the simulated world of the ``fake`` backend (issue 38).

Each effect can be switched (``capture --effects``); a camera session (``--camera fake``) has them all on
by default, an aimed one none (the world the README's and docs' figures were measured in). The values
that vary from table to table are drawn once per session from its seed and stored in session.yaml
(``simulated.world``), so that ``validate`` sees the same world.

* ``repeatability``: the pose the arm reaches differs from what its encoders report, by Gaussian joint
  noise of :data:`REPEAT_SIGMA_RAD` per joint -- Franka's datasheet repeatability, ISO 9283's RP
  (mean + 3 std of the distance) of 0.1 mm, at the laser aperture over aiming poses at a sheet 450 mm
  out (about 0.06 mm RMS at the spot). A new draw for every pose reached.
* ``distortion``: the camera's lens distorts radially (:data:`DISTORTION`); its calibration is known
  (as ``lasercal camera`` gives for a real one) and undone before the markers' homography.
* ``occlusion``: the arm (capsules of :data:`ARM_RADIUS_MM` along its links) hides the spot from the
  camera when it lies on the line of sight.
* ``ellipse``: a beam meeting the sheet at a tilt lights an elliptic footprint, 1/cos(tilt) longer along
  its azimuth (``vision.render.tilted_spot``).
* ``print-scale``: the printer scales the sheet by a factor drawn uniformly within +-0.2 % along each of
  its axes: markers, crosses and all (the operator aims at the printed crosses).
* ``sheet-height``: the sheet lies up to 0.5 mm above or below its stated plane (uniform draw).

Without ``occlusion`` the camera still sees the sheet from its stated pose (:func:`camera_pose`); without
``ellipse`` the footprint is round on the sheet (and perspective still makes it an ellipse in the photo).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lasercal.solver.errors import LasercalError

EFFECTS = ("repeatability", "distortion", "occlusion", "ellipse", "print-scale", "sheet-height")
REPEAT_SIGMA_RAD = 4.7e-5  # per joint: RP 0.1 mm at the aperture (ISO 9283), see the module docstring
PRINT_SCALE = 0.002  # a printer scales each axis by up to +-0.2 %
SHEET_HEIGHT_MM = 0.5  # the sheet lies up to 0.5 mm off its stated plane
DISTORTION = (-0.08, 0.03, 0.0, 0.0, 0.0)  # OpenCV's k1, k2, p1, p2, k3: a phone-like wide lens
ARM_RADIUS_MM = 60.0  # the arm's links as capsules of this radius (a Panda's are 110-130 mm thick)
BEAM_SIGMA_MM = 1.0  # the laser footprint's Gaussian sigma on the sheet at normal incidence, mm
# The camera: 1280 x 960 px, 0.33 mm/px at the sheet's centre, 600 mm above the sheet and 350 mm beyond its
# centre on the side away from the robot (its x axis), looking at the centre: the arm reaches over the
# sheet from the other side, and the camera looks under it.
CAMERA_PX = (1280, 960)
CAMERA_MM_PER_PX = 0.33
CAMERA_OFFSET_MM = (350.0, 0.0, 600.0)


def parse_effects(text: str | None, camera: bool) -> tuple:
    """The effects a ``--effects`` value switches on: ``all``, ``none`` or names separated by commas.

    Parameters
    ----------
    text : str or None, the option's value (None: all with a fake camera, none without)
    camera : bool, the session has a fake camera

    Raises
    ------
    LasercalError
        An unknown name, naming the option and the names it takes.
    """
    if text is None:
        return EFFECTS if camera else ()
    text = text.strip()
    if text == "all":
        return EFFECTS
    if text == "none":
        return ()
    names = [t.strip() for t in text.split(",")]
    bad = [t for t in names if t not in EFFECTS]
    if bad or not names:
        raise LasercalError(
            f"--effects {text!r}: unknown effect {bad[0] if bad else ''!r} (expected all, none or a comma "
            f"list of {', '.join(EFFECTS)})"
        )
    return tuple(e for e in EFFECTS if e in names)


@dataclass(frozen=True)
class World:
    """The effects of one simulated session and their drawn values.

    Attributes
    ----------
    effects : tuple of str, those switched on (:data:`EFFECTS`)
    print_scale : (2,) array, the printed sheet's scale along its x and y axes (1: exact)
    sheet_dz : float, the sheet's height above its stated plane, mm
    """

    effects: tuple = ()
    print_scale: np.ndarray = field(default_factory=lambda: np.ones(2))
    sheet_dz: float = 0.0

    @classmethod
    def draw(cls, effects, seed: int) -> World:
        """The world of a session with seed ``seed``: its table's draws (each keyed on its own)."""
        scale = np.ones(2)
        if "print-scale" in effects:
            scale = 1.0 + np.random.default_rng([seed, 0x9121]).uniform(-PRINT_SCALE, PRINT_SCALE, 2)
        dz = 0.0
        if "sheet-height" in effects:
            dz = float(np.random.default_rng([seed, 0x5EE7]).uniform(-SHEET_HEIGHT_MM, SHEET_HEIGHT_MM))
        return cls(tuple(e for e in EFFECTS if e in effects), scale, dz)

    @property
    def repeat_sigma(self) -> float:
        """Joint noise between the reached and the reported pose, rad (0: exact)."""
        return REPEAT_SIGMA_RAD if "repeatability" in self.effects else 0.0

    def has(self, effect: str) -> bool:
        return effect in self.effects

    def as_dict(self) -> dict:
        """What session.yaml stores (``simulated.world``)."""
        return {
            "effects": list(self.effects),
            "print_scale": [float(s) for s in self.print_scale],
            "sheet_dz_mm": float(self.sheet_dz),
            "repeatability_rad": self.repeat_sigma,
        }

    @classmethod
    def from_dict(cls, d) -> World:
        """The world session.yaml stored (None or missing: the clean world)."""
        if not isinstance(d, dict):
            return cls()
        effects = tuple(e for e in EFFECTS if e in (d.get("effects") or ()))
        scale = np.asarray(d.get("print_scale", [1.0, 1.0]), dtype=float)
        return cls(effects, scale, float(d.get("sheet_dz_mm", 0)))


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


def arm_capsules(model, q: np.ndarray) -> np.ndarray:
    """The arm's links at configuration q as segments (k, 2, 3) mm: between the feet of the common
    normals of successive joint axes (at q = 0), then to the laser aperture."""
    from lasercal.solver.kinematics.poe import poe_chain

    S = model.screws
    w, v = S[:, :3], S[:, 3:]
    pts = [np.zeros(3)]
    for i in range(len(S)):
        r = np.cross(w[i], v[i])  # the axis's point nearest the origin (|w| = 1)
        # the point on axis i nearest the previous point: a joint's place along its own axis
        pts.append(r + w[i] * np.dot(pts[-1] - r, w[i]))
    chain = poe_chain(S, q[None])[0]
    placed = [chain[max(i - 1, 0)][:3, :3] @ p + chain[max(i - 1, 0)][:3, 3] for i, p in enumerate(pts)]
    T = chain[-1]
    placed.append(T[:3, :3] @ model.aperture + T[:3, 3])
    P = np.array(placed)
    return np.stack([P[:-1], P[1:]], axis=1)


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
    """Where the simulated operator aims: each point as printed (scaled by the printer), ``beside`` it
    (sheet mm; a camera session aims on white paper next to the cross), on the sheet's true surface, in
    the true robot's frame (a sheet at its placement), name -> (3,) mm.

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
    """Where spots of the layout's frame (k, 2) mm truly are: as printed (scaled by the printer), on the
    sheet's true surface, in the true robot's frame (a sheet at its placement), (k, 3) mm."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    z = layout.plane_z + world.sheet_dz
    if layout.frame != "sheet":
        return np.c_[xy, np.full(len(xy), z)]
    return layout.sheet.to_base(xy * world.print_scale, z)
