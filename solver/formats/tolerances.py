"""Tolerances: the prior standard deviations of a robot's parameters by kind, read and validated.

What a real arm's parameters may be before any data (the prior of every fit, eq. P1 of
:mod:`solver.identify.prior`): :class:`Tolerances` by parameter kind, lengths mm, angles rad. The
defaults (:data:`DEFAULTS`) hold for a hand-assembled arm and a hand-mounted laser; a robot's data file
may state its own (``prior:`` in ``lasercal-robot/1``, :func:`robot_tolerances`), and a user's file
overrides both (``lasercal-prior/1``, :func:`load_tolerances`; docs/formats.md). A file format, so it
lives with the formats: the robot files validate their ``prior:`` section with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from lasercal.solver.errors import FormatError, warn
from lasercal.solver.formats.checks import load_yaml

FORMAT = "lasercal-prior/1"

# Each parameter of an identification has a kind; its prior sigma is the tolerance of that kind.
KINDS = {
    "axis": "axis_rad",  # a revolute joint's axis direction (eta wx, wy)
    "offset": "offset_mm",  # a revolute joint's axis position across the axis (eta qx, qy)
    "slide": "axis_rad",  # a prismatic joint's direction (eta vx, vy)
    "laser": "laser_rad",  # the laser beam's direction (eta_p)
    "aperture": "aperture_mm",  # the laser aperture at q = 0
    "tool": "tool_mm",  # a tool point at q = 0
    "target": "target_mm",  # a tracker target on the last link at q = 0
    "point": "point_mm",  # a reference point identified with the robot (point sessions)
    "sensor_rot": "sensor_rad",  # the 3-D sensor's frame, rotation
    "sensor_pos": "sensor_mm",  # the 3-D sensor's frame, translation
    "sheet_pos": "sheet_mm",  # a printed sheet's position on the table
    "sheet_yaw": "sheet_rad",  # a printed sheet's rotation on the table
    "sheet_scale": "print_scale",  # a printer's scale along a sheet's axis, minus 1
    "sheet_tilt": "table_tilt_rad",  # a sheet's rise per mm along its axis (the table against joint 1)
    "sheet_shear": "print_scale",  # a printer's shear (eq. S5), mm per mm: as wide as its scale error
    "sheet_curl": "table_tilt_rad",  # a sheet's curvature (eq. S6), 1/mm: the tilt's figure per mm, wide
    "joint_compliance": "compliance_rad_per_nm",
    "lateral_compliance": "compliance_rad_per_nm",  # a link bending across its joint (same tolerance)
    "encoder_eccentricity": "eccentricity_rad",
    "drift": "drift_rad_per_s",
    "joint_map": "joint_map_rad",
    "reference_point_offset": "point_offset_mm",
}


@dataclass(frozen=True)
class Tolerances:
    """Prior standard deviations by parameter kind (eq. P1) and the noise prior (eq. P3).

    Lengths mm, angles rad. ``inf`` is no prior for that kind.

    Attributes
    ----------
    axis_rad : float, a joint axis's direction (2 components per joint)
    offset_mm : float, a joint axis's position across it (2 components per joint)
    laser_rad : float, the laser direction (hand-mounted pointer)
    aperture_mm : float, the laser aperture's position at q = 0 (per axis)
    tool_mm : float, a tool point at q = 0 (per axis)
    target_mm : float, a tracker target on the last link (per axis; inf: wherever the closed-form start
        puts it)
    point_mm : float, a reference point identified with the robot (per axis)
    sensor_rad, sensor_mm : float, the 3-D sensor's frame (inf: anywhere)
    sheet_mm, sheet_rad : float, a printed sheet's placement on the table about its stated placement
    print_scale : float, a printer's scale error along each of a sheet's axes (dimensionless; 0.002 =
        0.2 %: office printers at 100 % scale within a few 0.1 %, and the sheet's bars catch more)
    table_tilt_rad : float, the table's (the sheet's) tilt from the plane normal to joint 1's axis, per
        axis (0.01: a robot bolted down a few mm out of level over its base)
    compliance_rad_per_nm : float, a joint compliance c (q_true = q + c tau)
    eccentricity_rad : float, an encoder eccentricity amplitude (a, b)
    drift_rad_per_s : float, a joint drift rate
    joint_map_rad : float, a knot of a joint error map (solver.kinematics.joint_map)
    point_offset_mm : float, a reference point's offset from where the layout says (per axis)
    noise_mm : dict measurement -> sigma_0, the nominal measurement noise per axis (mm)
    noise_dof : float, nu_0: pseudo-observations behind noise_mm
    """

    axis_rad: float = 0.01
    offset_mm: float = 3.0
    laser_rad: float = 0.03
    aperture_mm: float = 3.0
    tool_mm: float = 5.0
    target_mm: float = math.inf
    point_mm: float = math.inf
    sensor_rad: float = math.inf
    sensor_mm: float = math.inf
    sheet_mm: float = 50.0
    sheet_rad: float = math.radians(15.0)
    print_scale: float = 0.002
    table_tilt_rad: float = 0.01
    compliance_rad_per_nm: float = 1e-3
    eccentricity_rad: float = 1e-2
    drift_rad_per_s: float = 1e-5
    joint_map_rad: float = 3e-4  # 0.3 mrad: the UR10's angle errors beyond geometry (docs/real-data.md)
    point_offset_mm: float = 3.0
    noise_mm: tuple = (("laser", 1.0), ("point", 0.3), ("position", 0.02))
    noise_dof: float = 4.0

    def std(self, kinds) -> np.ndarray:
        """Prior sigmas s (p,) of parameters of the given kinds (eq. P1)."""
        return np.array([getattr(self, KINDS[k]) for k in kinds], dtype=float)

    def noise(self, measurement: str) -> float:
        """sigma_0 of a measurement type ('laser', 'point', 'position'), mm."""
        return dict(self.noise_mm)[measurement]

    def with_noise(self, measurement: str, mm: float) -> Tolerances:
        """These tolerances with sigma_0 of one measurement type set to ``mm``."""
        return replace(self, noise_mm=tuple((dict(self.noise_mm) | {measurement: float(mm)}).items()))

    def as_dict(self) -> dict:
        """The tolerances as a JSON- and YAML-ready mapping (no prior, inf, written as None)."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["noise_mm"] = dict(self.noise_mm)
        return {k: None if isinstance(v, float) and math.isinf(v) else v for k, v in d.items()}

    def updated(self, d: dict, path="<prior>", where: str = "prior") -> Tolerances:
        """These tolerances with the entries of a mapping ``d`` changed, validated.

        Raises
        ------
        FormatError
            An unknown key, or a value that is not a positive number (inf allowed; naming the field).
        """
        if not isinstance(d, dict):
            raise FormatError(path, "expected a mapping of tolerances (mm, rad)", field=where)
        known = {f.name for f in fields(self)}
        out = {}
        for k, v in d.items():
            if k not in known:
                raise FormatError(
                    path, f"unknown tolerance {k!r} (known: {', '.join(sorted(known))})", field=f"{where}.{k}"
                )
            if v is None:  # as_dict's "no prior"
                v = math.inf
            if k == "noise_mm":
                if not isinstance(v, dict) or set(v) - {"laser", "point", "position"}:
                    raise FormatError(
                        path, "noise_mm must map laser/point/position to mm", field=f"{where}.{k}"
                    )
                vals = dict(self.noise_mm) | {m: _positive(x, path, f"{where}.{k}.{m}") for m, x in v.items()}
                if any(math.isinf(x) for x in vals.values()):
                    raise FormatError(path, "a noise sigma must be finite (mm)", field=f"{where}.{k}")
                for m in v:
                    _plausible(vals[m], "mm", _NOISE_METRES_BELOW_MM, path, f"{where}.{k}.{m}")
                out[k] = tuple(vals.items())
            else:
                out[k] = _positive(v, path, f"{where}.{k}")
                _plausible(out[k], k.rsplit("_", 1)[-1], _TOL_METRES_BELOW_MM, path, f"{where}.{k}")
        if math.isinf(out.get("noise_dof", 1.0)):
            raise FormatError(path, "noise_dof must be finite", field=f"{where}.noise_dof")
        return replace(self, **out)


# A length tolerance (noise sigma) below these is tighter than any arm is made (any sensor measures): a
# value in metres; an angle tolerance above this (57 deg) is no prior at all: a value in degrees.
_TOL_METRES_BELOW_MM = 0.01
_NOISE_METRES_BELOW_MM = 1e-3
_DEGREES_ABOVE_RAD = 1.0


def _positive(v, path, field: str) -> float:
    try:
        x = float(v) if not isinstance(v, bool) else math.nan  # 'yes' is no tolerance
    except (TypeError, ValueError):
        x = math.nan
    if not x > 0:  # NaN fails too
        raise FormatError(path, f"{v!r} (expected a number > 0, or .inf for no prior)", field=field)
    return x


def _plausible(x: float, unit: str, metres_below: float, path, field: str) -> None:
    """Warn about a tolerance that looks like metres (a length below ``metres_below`` mm) or degrees
    (an angle above :data:`_DEGREES_ABOVE_RAD`); ``unit`` is its key's suffix ('mm', 'rad', 'nm', ...)."""
    if unit == "mm" and x < metres_below:
        warn(f"{path}, field '{field}': {x:g} mm is tighter than any arm or sensor: metres? (expected mm)")
    elif unit == "rad" and math.isfinite(x) and x > _DEGREES_ABOVE_RAD:
        warn(
            f"{path}, field '{field}': {x:g} rad ({math.degrees(x):.0f} deg) is hardly a prior: degrees? "
            "(expected rad)"
        )


DEFAULTS = Tolerances()


def robot_tolerances(model) -> Tolerances:
    """A robot's tolerances: its data file's ``prior:`` section over :data:`DEFAULTS`."""
    return DEFAULTS.updated(model.prior, f"robot {model.name}") if model.prior else DEFAULTS


def load_tolerances(spec, model) -> Tolerances | None:
    """The tolerances a command uses: ``spec`` 'none' (plain least squares), 'default' or None (the robot's
    own, :func:`robot_tolerances`), or a ``lasercal-prior/1`` YAML file that overrides them.

    Raises
    ------
    FormatError
        A file that cannot be read or is malformed (naming the file and field).
    """
    if spec is not None and str(spec).lower() == "none":
        return None
    base = robot_tolerances(model)
    if spec is None or str(spec).lower() == "default":
        return base
    d = load_yaml(spec)
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise FormatError(spec, f"expected a YAML mapping with 'format: {FORMAT}'", field="format")
    units = d.get("units") or {}
    if not isinstance(units, dict) or units.get("length", "mm") != "mm" or units.get("angle", "rad") != "rad":
        raise FormatError(spec, "units must be length: mm, angle: rad", field="units")
    # any other key would be ignored in silence ('priors:', a tolerance at the top): a fit on the defaults
    for k in d:
        if k in {f.name for f in fields(Tolerances)}:
            raise FormatError(spec, f"{k} is a tolerance: it belongs under 'prior:'", field=str(k))
        if k not in ("format", "units", "prior"):
            raise FormatError(spec, f"unknown key {k!r} (expected format, units, prior)", field=str(k))
    return base.updated(d.get("prior") or {}, spec)
