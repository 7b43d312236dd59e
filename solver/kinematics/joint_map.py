"""Joint error maps: a correction of each joint's angle that depends on that joint's own angle (eq. JM1).

q_true_j = q_j + sum_k c_jk B_k((q_j - a_j) / h), B the piecewise-linear hat functions on knots a_j + k h
(k = 0..K_j-1) covering the angles the fit saw, with one knot of margin each side. Linear in the knot values
c_jk (rad); each pose touches two knots per joint, so the regressor matrix is sparse. The values start at 0
and their prior (``joint_map_rad`` of :mod:`solver.formats.tolerances`) holds every knot the data do not see
at 0: outside what the fit saw the map is the geometric model's. What it models: repeatable errors of a
joint's angle that vary over a few degrees of that angle -- transmission (gear tooth) and encoder cyclic
errors -- which neither the geometry nor a gravity compliance can express (docs/real-data.md).

A map has the interface of a joint effect (:class:`~lasercal.solver.kinematics.effects.Extension`:
regressors, true_q, parameters and their names, model entries), so a position fit takes it as one part of a
:class:`~lasercal.solver.kinematics.effects.Combination` (:func:`with_joint_map`); a pose fit keeps its
regressors sparse (:meth:`JointMap.hats`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse

from lasercal.solver.errors import FormatError
from lasercal.solver.kinematics.effects import Combination, Extension, extension_from_model
from lasercal.solver.kinematics.joint_names import joint_tags

# knot spacing: the UR10's errors decorrelate over 0.1-0.3 rad of a joint. Chosen (with joint_map_rad
# 0.3 mrad) on the UR10's leave-one-series-out: 0.236 mm held out against 0.262-0.272 for 0.1 rad; chosen
# inside it (nested, benchmarks/bench_ur10.py), 0.05 rad won every fold: 0.233 mm (docs/real-data.md)
STEP_RAD = 0.05
# position sessions (solver.analysis.diagnose.joint_map_stage): hundreds of configurations, not the UR10's
# 16,000 poses -- DLR's Justin (280 of its records, its other 70 held out) predicted best at 0.5 rad of
# 0.2, 0.5 and 1 rad (docs/position.md)
POSITION_STEP_RAD = 0.5


@dataclass(frozen=True)
class JointMap:
    """Per-joint piecewise-linear angle corrections (eq. JM1).

    Attributes
    ----------
    joints : tuple of 1-based joints
    start : (len(joints),) array, rad, each joint's first knot
    step : float, rad, the knot spacing h
    counts : tuple of int, knots per joint
    params : (sum(counts),) array, rad, the knot values joint by joint
    std_errors : array or None
    joint_names : tuple of the model's n joint names (a tree's joints are named by name), or ()
    """

    joints: tuple
    start: np.ndarray
    step: float
    counts: tuple
    params: np.ndarray
    std_errors: np.ndarray | None = None
    joint_names: tuple = field(default=(), compare=False, repr=False)

    effect = "joint_map"
    acts_on_joints = True
    point = None

    @classmethod
    def covering(cls, q: np.ndarray, joints=None, step: float = STEP_RAD, joint_names=()) -> JointMap:
        """A zero map whose knots cover the angles (m, n) rad of the given joints (default all), one knot of
        margin each side."""
        q = np.atleast_2d(q)
        joints = tuple(range(1, q.shape[1] + 1)) if joints is None else tuple(joints)
        lo = np.array([q[:, j - 1].min() - step for j in joints])
        hi = np.array([q[:, j - 1].max() + step for j in joints])
        counts = tuple(int(np.ceil((b - a) / step)) + 1 for a, b in zip(lo, hi))
        return cls(joints, lo, float(step), counts, np.zeros(sum(counts)), None, tuple(joint_names))

    @property
    def size(self) -> int:
        return int(sum(self.counts))

    @property
    def tags(self) -> list:
        return joint_tags(self.joints, self.joint_names)

    @property
    def names(self) -> list:
        return [
            f"map{j}@{a + k * self.step:+.2f}" if j.isdigit() else f"map[{j}]@{a + k * self.step:+.2f}"
            for j, a, n in zip(self.tags, self.start, self.counts)
            for k in range(n)
        ]

    @property
    def kinds(self) -> list:
        return ["joint_map"] * self.size

    @property
    def units(self) -> list:
        return ["rad"] * self.size

    @property
    def parts(self) -> tuple:
        return (self,)

    @property
    def label(self) -> str:
        return f"joint_map at joints {','.join(self.tags)} (knots every {self.step:g} rad)"

    def needs(self) -> set:
        """Logged signals it needs: none (the angles alone)."""
        return set()

    def with_params(self, params, std_errors=None) -> JointMap:
        return JointMap(
            self.joints,
            self.start,
            self.step,
            self.counts,
            np.asarray(params, float),
            None if std_errors is None else np.asarray(std_errors, float),
            self.joint_names,
        )

    def regressors(self, q: np.ndarray, t=None, tau=None) -> tuple[np.ndarray, np.ndarray]:
        """Joint index (size,) 0-based of each knot and the hat-function values (m, size), dense: the
        interface of a joint effect (:meth:`Extension.regressors`)."""
        idx, G = self.hats(q)
        return idx, G.toarray()

    def hats(self, q: np.ndarray) -> tuple[np.ndarray, sparse.csr_matrix]:
        """Joint index (size,) 0-based of each knot and the hat-function values (m, size), sparse."""
        q = np.atleast_2d(q)
        m = len(q)
        rows, cols, vals, off = [], [], [], 0
        for j, a, n in zip(self.joints, self.start, self.counts):
            u = np.clip(
                (q[:, j - 1] - a) / self.step, 0.0, n - 1.0
            )  # beyond the knots: the end knot (0 a priori)
            i = np.minimum(np.floor(u).astype(int), n - 2)
            f = u - i
            r = np.arange(m)
            rows += [r, r]
            cols += [off + i, off + i + 1]
            vals += [1 - f, f]
            off += n
        G = sparse.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, off)
        )
        idx = np.repeat(np.array(self.joints, int) - 1, self.counts)
        return idx, G

    def correction(self, q: np.ndarray) -> np.ndarray:
        """dq (m, n) rad added to the logged angles."""
        q = np.atleast_2d(q)
        idx, G = self.hats(q)
        dq = np.zeros_like(q, dtype=float)
        contrib = G.multiply(self.params[None, :]).tocsc()
        for j in set(idx.tolist()):
            dq[:, j] = np.asarray(contrib[:, idx == j].sum(axis=1)).ravel()
        return dq

    def true_q(self, q: np.ndarray, t=None, tau=None) -> np.ndarray:
        return np.atleast_2d(q) + self.correction(q)

    logged_q = Extension.logged_q

    def target_offset(self, point_names: np.ndarray, aimed: np.ndarray | None = None) -> np.ndarray:
        return np.zeros((len(point_names), 2))

    def to_dict(self) -> dict:
        d = {
            "units": "rad",
            "joints": [int(j) for j in self.joints],
            "step": float(self.step),
            "start": [float(a) for a in self.start],
            "values": [[float(v) for v in p] for p in np.split(self.params, np.cumsum(self.counts)[:-1])],
        }
        if self.std_errors is not None:
            d["std_errors"] = [
                [float(v) for v in p] for p in np.split(self.std_errors, np.cumsum(self.counts)[:-1])
            ]
        return d

    def model_entries(self) -> dict:
        return {"joint_map": self.to_dict()}


def joint_map_from_model(extensions: dict, path="<model>", n: int | None = None) -> JointMap | None:
    """The ``extensions.joint_map`` entry of a model file, validated (None when absent)."""
    d = (extensions or {}).get("joint_map")
    if d is None:
        return None
    where = "extensions.joint_map"
    try:
        joints = tuple(int(j) for j in d["joints"])
        step = float(d["step"])
        start = np.array(d["start"], dtype=float)
        values = [np.array(v, dtype=float) for v in d["values"]]
    except (KeyError, TypeError, ValueError):
        raise FormatError(
            path, "joint_map needs 'joints', 'step', 'start' and 'values' (rad)", field=where
        ) from None
    ok = (
        len(start) == len(joints) == len(values)
        and step > 0
        and all(len(v) >= 2 for v in values)
        and np.all(np.isfinite(start))
        and all(np.all(np.isfinite(v)) for v in values)
        and (n is None or all(1 <= j <= n for j in joints))
    )
    if not ok:
        raise FormatError(
            path,
            "joint_map: one start and one list of >= 2 finite knot values per joint, step > 0",
            field=where,
        )
    return JointMap(joints, start, step, tuple(len(v) for v in values), np.concatenate(values))


def with_joint_map(ext, jm: JointMap | None):
    """A joint effect and a joint map as one (a :class:`Combination`; either alone when the other is None)."""
    if jm is None or ext is None:
        return jm if ext is None else ext
    return Combination(tuple(ext.parts) + (jm,))


def split_joint_map(ext) -> tuple:
    """(the joint effect without the map or None, the JointMap or None) of :func:`with_joint_map`'s result."""
    parts = () if ext is None else ext.parts
    jm = next((e for e in parts if isinstance(e, JointMap)), None)
    rest = [e for e in parts if not isinstance(e, JointMap)]
    return (rest[0] if len(rest) == 1 else Combination(tuple(rest)) if rest else None), jm


def model_extension(extensions: dict, path="<model>", n: int | None = None):
    """Every joint effect a model file carries, its joint map included (:func:`with_joint_map`): what
    predict and correct apply to the logged angles."""
    return with_joint_map(
        extension_from_model(extensions, path, n), joint_map_from_model(extensions, path, n)
    )
