"""Catalogue of non-geometric effects: small extensions of the geometric model.

Each effect adds a few parameters and is linear in them:

* ``joint_compliance``      q_true_i = q_logged_i + c_i tau_i             (c: rad/Nm)
* ``encoder_eccentricity``  q_true_i = q_logged_i + a_i sin q_i + b_i cos q_i   (a, b: rad)
* ``drift``                 q_true_i = q_logged_i + r_i (t - t0)          (r: rad/s; t0 s, 0 in a model file)
* ``reference_point_offset`` the true point is the session's point + (dx, dy)    (mm)
* ``lateral_compliance``    q_true_i = 0 + c_i tau_i on a lateral axis i (an axis across a joint about
  which its link bends, :mod:`solver.kinematics.tree`; tau_i the moment of gravity about it)  (c: rad/Nm)

A :class:`Combination` applies several joint effects at once (e.g. compliance on joints 2-3 and
eccentricity on joint 4): q_true = q_logged + sum over its parts of their corrections, each
evaluated at the logged angles (so the parameters stay linear and the Jacobian exact). In a model
file it is simply several entries of ``extensions`` (one per effect).

Sign convention: tau is the torque that holds the arm still against gravity, tau = dV/dq
(:mod:`solver.gravity`, libfranka's ``tau_J`` at standstill). A joint that yields under load
turns down the gradient, so a physical sag has c < 0 and the joint's stiffness is k = -1/c.

A joint effect is written as q_true = q_logged + sum_k p_k g_k e_{j_k}: parameter k acts
on joint j_k through the regressor g_k(q, t, tau) (m,). The spot's derivative with respect
to p_k is then the spot's joint Jacobian column j_k times g_k.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from lasercal.solver.errors import FormatError, ModelError
from lasercal.solver.kinematics.joint_names import joint_tags, parameter_name

JOINT_EFFECTS = ("joint_compliance", "encoder_eccentricity", "drift", "lateral_compliance")
EFFECTS = JOINT_EFFECTS + ("reference_point_offset", "none")
# Robot effects a controller can apply at run time from q (tau from the gravity model when not logged):
# they belong to the robot and go into MODEL.yaml. Session effects explain one session's data (the
# clock of this session, where this table's point really is) but are not part of the robot: they are
# fitted, so that they do not bend the geometry, and reported, never exported.
ROBOT_EFFECTS = ("joint_compliance", "encoder_eccentricity", "lateral_compliance", "joint_map")
SESSION_EFFECTS = ("drift", "reference_point_offset")
UNITS = {
    "joint_compliance": "rad/Nm",
    "lateral_compliance": "rad/Nm",
    "encoder_eccentricity": "rad",
    "drift": "rad/s",
    "reference_point_offset": "mm",
}
_PARAMS = {
    "joint_compliance": ("c",),
    "lateral_compliance": ("c",),
    "encoder_eccentricity": ("a", "b"),
    "drift": ("r",),
    "reference_point_offset": ("dx", "dy"),
}


@dataclass(frozen=True)
class Extension:
    """One effect applied to some joints (1-based) or to one reference point, with its parameters.

    ``params`` is ordered joint by joint, then by the effect's parameter names
    (e.g. a_2, b_2, a_4, b_4 for eccentricity on joints 2 and 4), or (dx, dy) for a point.
    ``joint_names`` are the model's joint names (all n), so that what a person reads names a tree's joints
    by name (:mod:`solver.kinematics.joint_names`); empty: by number.
    """

    effect: str
    joints: tuple = ()
    point: str | None = None
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    std_errors: np.ndarray | None = None
    joint_names: tuple = field(default=(), compare=False, repr=False)
    # drift: the instant (s, the session's clock) at which it is zero, so that the geometry fitted beside it
    # is the arm's then. A diagnosis sets the session's mean capture time: the geometry's least-uncertain
    # instant, and the one a geometric fit without the drift describes (a spurious drift cannot move it)
    t0: float = 0.0

    @property
    def size(self) -> int:
        """Number of parameters."""
        per = len(_PARAMS[self.effect])
        return per * (len(self.joints) if self.effect in JOINT_EFFECTS else 1)

    @property
    def tags(self) -> list[str]:
        """How each of its joints is named: '2' (a serial arm's number) or 'torso_2' (a tree's name)."""
        return joint_tags(self.joints, self.joint_names)

    @property
    def names(self) -> list[str]:
        """Parameter names, e.g. 'c2', 'c[torso_2]' or 'P2.dx'."""
        if self.effect == "reference_point_offset":
            return [f"{self.point}.dx", f"{self.point}.dy"]
        return [parameter_name(p, t) for t in self.tags for p in _PARAMS[self.effect]]

    @property
    def kinds(self) -> list[str]:
        """The prior kind of each parameter (:mod:`solver.identify.prior`): the effect's name."""
        return [self.effect] * self.size

    @property
    def parts(self) -> tuple:
        """The single-effect extensions it consists of (itself)."""
        return (self,)

    @property
    def acts_on_joints(self) -> bool:
        """Whether it corrects joint angles (every effect but a reference-point offset)."""
        return self.effect in JOINT_EFFECTS

    @property
    def units(self) -> list[str]:
        """Unit of each parameter."""
        return [UNITS[self.effect]] * self.size

    @property
    def label(self) -> str:
        """'joint_compliance at joints 2,3', 'joint_compliance at joint torso_2' or
        'reference_point_offset at P2'."""
        if self.point:
            return f"{self.effect} at {self.point}"
        return f"{self.effect} at joint{'s' if len(self.joints) > 1 else ''} {','.join(self.tags)}"

    def model_entries(self) -> dict:
        """The model file's ``extensions`` entries: effect -> :meth:`to_dict`."""
        return {self.effect: self.to_dict()}

    def with_params(self, params, std_errors=None) -> Extension:
        return replace(
            self,
            params=np.asarray(params, float),
            std_errors=None if std_errors is None else np.asarray(std_errors, float),
        )

    def needs(self) -> set:
        """Which logged signals the effect needs: 'tau', 't' or nothing."""
        return {"joint_compliance": {"tau"}, "lateral_compliance": {"tau"}, "drift": {"t"}}.get(
            self.effect, set()
        )

    # ------------------------------------------------------------ joint effects
    def regressors(
        self, q: np.ndarray, t: np.ndarray | None, tau: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint index (k,) (0-based) and regressor values (m, k) of each parameter.

        Parameters
        ----------
        q : (m, n) array, logged joint angles, rad
        t : (m,) array, s (drift)
        tau : (m, n) array, Nm (compliance)
        """
        cols, joints = [], []
        for j in self.joints:
            i = j - 1
            if self.effect in ("joint_compliance", "lateral_compliance"):
                cols.append(tau[:, i])
            elif self.effect == "encoder_eccentricity":
                cols += [np.sin(q[:, i]), np.cos(q[:, i])]
            elif self.effect == "drift":
                cols.append(t - self.t0)
            joints += [i] * len(_PARAMS[self.effect])
        return np.array(joints, dtype=int), np.stack(cols, axis=1) if cols else np.zeros((len(q), 0))

    def true_q(self, q: np.ndarray, t: np.ndarray | None = None, tau: np.ndarray | None = None) -> np.ndarray:
        """q_true (m, n) from the logged q (unchanged for a point offset)."""
        if not self.acts_on_joints or not self.joints:
            return q
        idx, G = self.regressors(q, t, tau)
        dq = np.zeros_like(q)
        np.add.at(dq.T, idx, (G * self.params).T)
        return q + dq

    def logged_q(
        self,
        q_true: np.ndarray,
        t: np.ndarray | None = None,
        tau: np.ndarray | None = None,
        iterations: int = 6,
    ) -> np.ndarray:
        """The logged angles (m, n) whose corrected angles are ``q_true``: the inverse of :meth:`true_q`.

        Fixed-point iteration q = q_true - dq(q); it converges fast because dq is milliradians.
        """
        q = np.array(q_true, dtype=float)
        for _ in range(iterations):
            q = q_true - (self.true_q(q, t, tau) - q)
        return q

    def target_offset(self, point_names: np.ndarray, aimed: np.ndarray | None = None) -> np.ndarray:
        """(m, 2) mm added to the session's targets (only a reference_point_offset moves them); ``aimed``
        (m,) bool: the captures aimed at their point (default all; a camera's measured spot is where the
        beam was, whatever the point's position)."""
        off = np.zeros((len(point_names), 2))
        if self.effect == "reference_point_offset":
            off[(point_names == self.point) & (True if aimed is None else aimed)] = self.params[:2]
        return off

    # ------------------------------------------------------------ model file
    def to_dict(self) -> dict:
        d = {"units": UNITS[self.effect]}
        if self.effect == "reference_point_offset":
            d["point"] = self.point
        else:
            d["joints"] = [int(j) for j in self.joints]
        if self.effect == "drift" and self.t0:
            d["t0_s"] = float(self.t0)
        for k, name in enumerate(_PARAMS[self.effect]):
            vals = self.params[k :: len(_PARAMS[self.effect])]
            d[name] = [float(v) for v in vals]
            if self.std_errors is not None:
                d[f"{name}_std_error"] = [float(v) for v in self.std_errors[k :: len(_PARAMS[self.effect])]]
        return d


@dataclass(frozen=True)
class Combination:
    """Several joint effects applied together: q_true = q_logged + sum_k dq_k(q_logged, t, tau).

    The interface of :class:`Extension` (parameters concatenated part by part, in the order of
    ``parts``), so every fit, prediction and export takes either.

    Attributes
    ----------
    parts : tuple of Extension, joint effects, at most one per effect family
    """

    parts: tuple

    def __post_init__(self):
        effects = [e.effect for e in self.parts]
        if (
            len(self.parts) < 2
            or len(set(effects)) != len(effects)
            or not all(e.acts_on_joints for e in self.parts)
        ):
            raise ModelError(f"a combination takes two or more different joint effects, not {effects}")

    effect = property(lambda self: "+".join(e.effect for e in self.parts), doc="'joint_compliance+...'")
    joints = property(lambda self: tuple(sorted({j for e in self.parts for j in e.joints})))
    point = None
    acts_on_joints = True
    params = property(lambda self: np.concatenate([e.params for e in self.parts]))
    size = property(lambda self: sum(e.size for e in self.parts))
    names = property(lambda self: [n for e in self.parts for n in e.names])
    kinds = property(lambda self: [k for e in self.parts for k in e.kinds])
    units = property(lambda self: [u for e in self.parts for u in e.units])
    label = property(lambda self: " + ".join(e.label for e in self.parts))
    tags = property(lambda self: joint_tags(self.joints, self.parts[0].joint_names))

    @property
    def std_errors(self) -> np.ndarray | None:
        if any(e.std_errors is None for e in self.parts):
            return None
        return np.concatenate([e.std_errors for e in self.parts])

    def _split(self, x) -> list:
        return np.split(np.asarray(x, float), np.cumsum([e.size for e in self.parts])[:-1])

    def with_params(self, params, std_errors=None) -> Combination:
        se = [None] * len(self.parts) if std_errors is None else self._split(std_errors)
        return Combination(tuple(e.with_params(p, s) for e, p, s in zip(self.parts, self._split(params), se)))

    def needs(self) -> set:
        return set().union(*(e.needs() for e in self.parts))

    def regressors(self, q, t, tau) -> tuple[np.ndarray, np.ndarray]:
        """Joint index (k,) and regressor values (m, k) of every parameter, part by part."""
        idx, G = zip(*(e.regressors(q, t, tau) for e in self.parts))
        return np.concatenate(idx), np.concatenate(G, axis=1)

    true_q = Extension.true_q
    logged_q = Extension.logged_q

    def target_offset(self, point_names: np.ndarray, aimed: np.ndarray | None = None) -> np.ndarray:
        return np.zeros((len(point_names), 2))

    def model_entries(self) -> dict:
        """One ``extensions`` entry per part."""
        return {e.effect: e.to_dict() for e in self.parts}


def combine(parts) -> Extension | Combination:
    """One extension from parts (a Combination when there are several), ordered as the catalogue."""
    if len(parts) == 1:
        return parts[0]
    return Combination(tuple(sorted(parts, key=lambda e: JOINT_EFFECTS.index(e.effect))))


def robot_extensions(extensions: dict) -> dict:
    """The model file's ``extensions`` mapping restricted to robot effects (what MODEL.yaml exports)."""
    return {k: v for k, v in (extensions or {}).items() if k in ROBOT_EFFECTS}


def extension_from_model(
    extensions: dict, path="<model>", n: int | None = None
) -> Extension | Combination | None:
    """The joint effect(s) a model file carries in ``extensions``, validated: an Extension, a
    Combination when it carries several effects, or None."""
    # joint_map (solver.kinematics.joint_map, pose models) is read by joint_map_from_model
    unknown = [e for e in (extensions or {}) if e not in EFFECTS and e != "joint_map"]
    if unknown:
        raise FormatError(
            path,
            f"unknown extension {unknown[0]!r} (known: {', '.join(EFFECTS[:-1])})",
            field=f"extensions.{unknown[0]}",
        )
    parts = []
    for name in (e for e in JOINT_EFFECTS if e in (extensions or {})):
        d = extensions[name]
        try:
            joints = tuple(int(j) for j in d["joints"])
            cols = [np.array(d[p], dtype=float) for p in _PARAMS[name]]
        except (KeyError, TypeError, ValueError):
            raise FormatError(
                path,
                f"extension {name} needs 'joints' and {', '.join(_PARAMS[name])} lists",
                field=f"extensions.{name}",
            ) from None
        if not all(np.all(np.isfinite(c)) for c in cols):
            raise FormatError(
                path,
                f"extension {name}: every coefficient must be a finite number",
                field=f"extensions.{name}",
            )
        if any(len(c) != len(joints) for c in cols) or (
            n is not None and any(not 1 <= j <= n for j in joints)
        ):
            raise FormatError(
                path,
                f"extension {name}: one value per joint, joints numbered 1..{n}",
                field=f"extensions.{name}",
            )
        t0 = d.get("t0_s", 0.0) if name == "drift" else 0.0
        if not isinstance(t0, (int, float)) or not np.isfinite(t0):
            raise FormatError(
                path,
                f"extension drift: t0_s must be a finite number of s, got {t0!r}",
                field="extensions.drift.t0_s",
            )
        parts.append(Extension(name, joints, None, np.stack(cols, axis=1).ravel(), t0=float(t0)))
    return combine(parts) if parts else None


def drift_t0(extension) -> float | None:
    """The instant (s) at which an extension's drift is zero (:attr:`Extension.t0`), None without a drift."""
    parts = [] if extension is None else [e for e in extension.parts if e.effect == "drift"]
    return float(parts[0].t0) if parts else None


def candidates(
    n: int, points, has_tau: bool, has_t: bool, lateral=(), joint_names=(), t0: float = 0.0
) -> list[Extension]:
    """Every single-joint (or single-point) extension the data can test.

    Parameters
    ----------
    n : int, joints
    points : reference points an offset may move (none for point sessions)
    has_tau : bool, torques logged or from a gravity model
    has_t : bool, a real clock that changes (``clock: seconds``): drift needs time, not row order
    lateral : 1-based joints that are lateral axes (they only bend: ``lateral_compliance`` is their effect)
    joint_names : the model's n joint names (how the candidates name their joints), optional
    t0 : float, s, the instant at which a drift candidate is zero (:attr:`Extension.t0`)
    """
    out = []
    for effect in JOINT_EFFECTS:
        if (effect in ("joint_compliance", "lateral_compliance") and not has_tau) or (
            effect == "drift" and not has_t
        ):
            continue
        on = [j for j in range(1, n + 1) if (j in lateral) == (effect == "lateral_compliance")]
        at = t0 if effect == "drift" else 0.0
        out += [
            Extension(effect, (j,), None, np.zeros(len(_PARAMS[effect])), None, joint_names, at) for j in on
        ]
    out += [Extension("reference_point_offset", (), p, np.zeros(2)) for p in points]
    return out


def untested(measurement: str, has_tau: bool, clock: str, t_changes: bool, frame: str = "base") -> dict:
    """Effects of the catalogue the data cannot test, with the reason (for the report); ``frame``: the
    layout's ('sheet': points printed, not measured)."""
    out = {}
    if not has_tau:
        out["joint_compliance"] = "no logged torques and no gravity model of the robot"
    if clock != "seconds":
        out["drift"] = (
            f"the session has no clock (clock: {clock}): t is the recording order, and a drift fitted to "
            "it would be a fit to a made-up regressor"
        )
    elif not t_changes:
        out["drift"] = "t does not change over the session"
    if measurement == "point":
        out["reference_point_offset"] = "point sessions identify their points (an offset is absorbed)"
    elif measurement == "laser" and frame == "sheet":
        out["reference_point_offset"] = (
            "the points are printed, where the printer put them (its scale and the sheet's tilt are fitted "
            "with the sheet's pose): an offset is a measured layout's mistake"
        )
    return out


def require(ext: Extension, t, tau) -> None:
    """Raise when the data lack what the effect needs."""
    if "tau" in ext.needs() and tau is None:
        raise ModelError(
            "joint_compliance needs joint torques (tau1..tauN columns, or a robot gravity model)"
        )
    if "t" in ext.needs() and t is None:
        raise ModelError("drift needs the capture time t")
