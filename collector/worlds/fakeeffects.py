"""A true robot's ``extensions`` on the fake arm (issues 45, 52): its encoders report q while its links stand
where the effects put them.

The fake backend's true robot (``--truth ROBOT.yaml``) may carry the effects a model file holds
(:mod:`solver.kinematics.effects`, :mod:`solver.kinematics.joint_map`). The file is checked here with the
solver's readers (a malformed entry is refused naming the file and field, as every model file is); the
physics is the world's own (:mod:`collector.worlds.truejoints`, eqs. W4-W6), not the solver's
``deflected`` or ``gravity_torques``, so that a diagnosis is tested on data its own forms did not draw:

* joint effects (``joint_compliance``, ``encoder_eccentricity``, ``drift``, and a ``joint_map``): with the
  encoders at q at the session's time t (captures.csv's ``t``), the links stand at the fixed point

      q_link = q + dq(q, t, tau(q_link)),

  tau the true gravity torques at the links' pose: the truth's ``links`` with the flange's load it records
  (``identification.payload``, :func:`solver.control.nominal.recorded_payload`); the torque sensor reads
  those torques (plus its noise). A commanded move servoes the encoders, the links follow.
* where the operator brings the links (aiming the true beam), the encoders read the inverse
  q = q_link - dq(q, t, tau(q_link)).
* ``reference_point_offset`` on a layout measured in the base frame: the point truly lies (dx, dy) mm from
  where the layout says, and the simulated operator aims there.

What the fake world cannot be is refused with the truth's file and the field (:func:`arm_effects`):
``lateral_compliance`` (the fake arm is a serial chain; lateral axes belong to tree models, which laser
sessions do not take), a compliance without a gravity model to bend under, a point offset on a printed
sheet (the print is exact: a cross lies where the layout says) or at a point the layout lacks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lasercal.collector.worlds.truejoints import TrueJoints, true_joints
from lasercal.solver.errors import FormatError
from lasercal.solver.kinematics.effects import extension_from_model
from lasercal.solver.kinematics.joint_map import joint_map_from_model
from lasercal.solver.kinematics.model import RobotModel

REFUSED = {
    "lateral_compliance": "the fake arm is a serial chain without lateral axes (a tree model's, which laser "
    "sessions do not take): it cannot bend across a joint",
}


@dataclass(frozen=True)
class ArmEffects:
    """The fake arm's effects beyond its geometry.

    Attributes
    ----------
    joints : TrueJoints, the world's joints (its gravity torques, eq. W4, zero for a truth without a gravity
        model; its joint errors, eq. W5)
    moves : bool, the truth holds joint effects (else the encoders read the links' angles)
    offsets : dict point -> (2,) array, mm, where a layout's point truly lies off its stated position
    """

    joints: TrueJoints
    moves: bool = False
    offsets: dict = field(default_factory=dict)

    def torques(self, q_link: np.ndarray) -> np.ndarray:
        """The true gravity torques (m, n) Nm at the links' pose (m, n) rad (eq. W4)."""
        return self.joints.torques(q_link)

    def links(self, q: np.ndarray, t: float) -> np.ndarray:
        """Where the links stand (m, n) rad when the encoders read q (m, n) at session time t (s), eq. W6."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        return self.joints.links(q, np.full(len(q), float(t))) if self.moves else q

    def encoders(self, q_link: np.ndarray, t: float) -> np.ndarray:
        """What the encoders read (m, n) rad with the links at q_link (m, n) at session time t (s): the
        inverse of :meth:`links` (the torques are the links' pose's, so the inverse is exact)."""
        q_link = np.atleast_2d(np.asarray(q_link, dtype=float))
        return self.joints.encoders(q_link, np.full(len(q_link), float(t))) if self.moves else q_link

    def aimed_points(self, points: dict) -> dict:
        """Where the layout's points (name -> (3,) mm) truly lie: moved by their offsets."""
        return {
            k: np.asarray(p, dtype=float) + np.r_[self.offsets.get(k, np.zeros(2)), 0.0]
            for k, p in points.items()
        }


def arm_effects(truth: RobotModel, source=None, points=None, printed: bool = False) -> ArmEffects:
    """The fake arm's effects from a true robot's ``extensions``, or a refusal naming what it cannot be.

    Parameters
    ----------
    truth : RobotModel, the true robot (its ``extensions``, ``links`` and ``identification.payload``)
    source : str or Path, the truth's file (named in errors; default its name)
    points : iterable of str or None, the layout's point names (a point offset must name one; None: unchecked)
    printed : bool, the points are a printed sheet's crosses (a point offset is refused)

    Returns
    -------
    ArmEffects

    Raises
    ------
    FormatError
        Naming the truth's file and ``extensions.EFFECT``: an effect the fake arm cannot simulate, a
        compliance without a gravity model, a point offset on a printed sheet or at a point not in the layout,
        a malformed entry.
    """
    from lasercal.solver.control.nominal import recorded_payload

    source = truth.name if source is None else source
    ext = dict(truth.extensions or {})
    for name, why in REFUSED.items():
        if name in ext:
            raise FormatError(source, f"{name}: {why}", field=f"extensions.{name}")
    joint = extension_from_model(ext, source, truth.n)
    jmap = joint_map_from_model(ext, source, truth.n)
    if joint is not None and "tau" in joint.needs() and not truth.links:
        raise FormatError(
            source,
            "joint_compliance: the truth has no gravity model ('links' with masses and centres of mass) to "
            "bend under",
            field="extensions.joint_compliance",
        )
    offsets = point_offsets(ext.get("reference_point_offset"), source, points, printed)
    moves = joint is not None or jmap is not None
    joints = true_joints(truth, recorded_payload(truth, source))
    return ArmEffects(joints, moves, offsets)


def point_offsets(entry, source, points=None, printed: bool = False) -> dict:
    """A model file's ``extensions.reference_point_offset`` ({point, dx, dy}, mm) as point -> (2,) mm."""
    if entry is None:
        return {}
    where = "extensions.reference_point_offset"
    if printed:
        raise FormatError(
            source,
            "reference_point_offset: a printed sheet's crosses lie where its layout says (the print is "
            "exact; its scale and tilt are the sheet's): a point offset needs a layout measured in the base "
            "frame",
            field=where,
        )
    try:
        name = str(entry["point"])
        d = np.array([np.ravel(entry["dx"])[0], np.ravel(entry["dy"])[0]], dtype=float)
    except (KeyError, TypeError, ValueError, IndexError):
        raise FormatError(
            source, "reference_point_offset needs 'point', 'dx' and 'dy' (mm)", field=where
        ) from None
    if not np.all(np.isfinite(d)):
        raise FormatError(
            source, "reference_point_offset: dx and dy must be finite numbers (mm)", field=where
        )
    if points is not None and name not in set(points):
        raise FormatError(
            source, f"reference_point_offset: the layout has no point {name!r}", field=f"{where}.point"
        )
    return {name: d}
