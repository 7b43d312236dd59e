"""Held-out accuracy of pose models and the choice of ``--extend auto`` for pose sessions.

The protocol (the issue's, and the outside check's): a model fitted on some sessions is placed anew on a
held-out session -- its frames (sensor and tool) re-fitted on one half of the session's poses
(:func:`register`) -- and scored on the other half, then the halves are swapped (:func:`half_scores`). The
halves are the first and second half in recording order: the later half was measured after the earlier.

``--extend auto`` (:func:`extend_auto`) compares the geometric model, joint compliance under gravity on the
joints the gravity model loads, and that plus a joint error map (:mod:`solver.kinematics.joint_map`) by this
protocol over the sessions (leave one session out; one session: three blocks of rows in order), and keeps
the one with the lowest held-out score (position mean / sigma_pos + rotation mean / sigma_rot, the noise
levels of the geometric fit). That table chooses and scores on the same folds, so its best score is
optimistic by the choice: the choice is also made inside each outer fold (:func:`nested_choices`), from a
leave-one-out over that fold's training units alone, and the outer folds' scores of their own choices are
the held-out figure reported. The choice is kept only when all but at most one outer fold made it too (the
agreement rule of :func:`~lasercal.solver.analysis.nested.fold_agreement`); otherwise the geometry is kept
and the folds' choices are said. Each fold's fit is its own: from the nominal robot, its frames from the
closed-form start, its own rotation/position noise ratio, a joint map's knots over its own angles --
nothing of the held-out session reaches it (a start from the whole data's fit would carry it: the
directions the fold cannot identify stay where the start put them). The map's knot step and prior are
the defaults (``STEP_RAD`` of :mod:`~lasercal.solver.kinematics.joint_map`, ``joint_map_rad``);
benchmarks/bench_ur10.py chooses them inside its own leave-one-series-out (nested), to measure what
choosing them on the data costs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lasercal.solver.analysis.nested import AGREE_ALL_BUT
from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.poses import PoseSession
from lasercal.solver.identify.poses import PoseFit, errors, fit_poses, session_frames
from lasercal.solver.kinematics.effects import Extension
from lasercal.solver.kinematics.gravity import model_torques
from lasercal.solver.kinematics.joint_map import JointMap
from lasercal.solver.kinematics.model import RobotModel

TORQUE_RANGE_NM = (
    5.0  # a joint whose gravity torque spans less than this over the data is not a compliance candidate
)
MIN_SPLIT = 12  # poses in a half below which a session is too small to be split for scoring


def register(model: RobotModel, session: PoseSession) -> PoseFit:
    """The model placed on a session: its robot (screws, extension, map) kept, the session's sensor and
    tool frames fitted (``lasercal register``)."""
    return fit_poses([session], model, joints=False)


def predict_session(fit: PoseFit, session: PoseSession) -> np.ndarray:
    """Predicted frames (m, 4, 4) of a session's poses by a registered model (its only session's frames)."""
    X, M = next(iter(fit.frames.values()))
    return session_frames(fit.model, session.q, X, M, fit.effects)


def half_scores(model: RobotModel, session: PoseSession) -> tuple[np.ndarray, np.ndarray]:
    """Per-pose held-out errors of a session: frames registered on each half, the other half predicted.

    Returns
    -------
    position (m,) mm and rotation angle (m,) rad, each pose predicted from the half it is not in
    """
    m = session.m
    if m < 2 * MIN_SPLIT:
        raise IdentificationError(
            f"{session.name}: {m} poses are too few to register on one half and score the other"
        )
    h = m // 2
    pos, rot = np.empty(m), np.empty(m)
    for a, b in ((np.arange(h), np.arange(h, m)), (np.arange(h, m), np.arange(h))):
        T = predict_session(register(model, session.subset(a)), session.subset(b))
        pos[b], rot[b] = errors(T, session.T[b])
    return pos, rot


@dataclass(frozen=True)
class Candidate:
    """A model family of ``--extend auto``: a label, a joint extension (or None) and a joint map (or None)."""

    label: str
    extension: Extension | None = None
    joint_map: JointMap | None = None


def candidates(nominal: RobotModel, sessions: list) -> list:
    """Geometric; + joint compliance on the joints the gravity model loads (torque range over the data above
    :data:`TORQUE_RANGE_NM`); + a joint error map on every joint (knots over the angles of every session)."""
    out = [Candidate("geometric")]
    q = np.vstack([s.q for s in sessions])
    comp = None
    if nominal.links:
        tau = model_torques(nominal, q)[0]
        joints = tuple(int(j) + 1 for j in np.flatnonzero(np.ptp(tau, axis=0) > TORQUE_RANGE_NM))
        if joints:
            comp = Extension("joint_compliance", joints, None, np.zeros(len(joints)))
            out.append(Candidate(f"joint compliance (joints {','.join(map(str, joints))})", comp))
    label = "joint compliance + joint error map" if comp else "joint error map"
    out.append(Candidate(label, comp, JointMap.covering(q)))
    return out


def covering(jm: JointMap | None, sessions: list) -> JointMap | None:
    """The map ``jm`` (its joints and knot step) anew, its knots over the angles of these sessions."""
    return jm and JointMap.covering(np.vstack([s.q for s in sessions]), jm.joints, jm.step)


def folds(sessions: list) -> list:
    """Leave-one-out units: the sessions, or one session's three blocks of rows in order (as sessions)."""
    if len(sessions) > 1:
        return list(sessions)
    s = sessions[0]
    parts = np.array_split(np.arange(s.m), 3)
    return [_renamed(s.subset(p), f"{s.name}.block{k + 1}") for k, p in enumerate(parts)]


def _renamed(s: PoseSession, name: str) -> PoseSession:
    from dataclasses import replace

    return replace(s, path=s.path.with_name(name))


@dataclass(frozen=True)
class AutoResult:
    """What ``--extend auto`` measured and chose.

    Attributes
    ----------
    fit : PoseFit, the kept candidate fitted on every session (the geometry when the folds disagreed)
    table : list of dict, per candidate: label, held-out position and rotation means (mm, mrad), score, train
    chosen : str, the kept candidate's label
    seconds : float
    best : str, the label the whole table scores best
    folds : tuple of dict, per outer fold: 'held' (unit name), 'chose' (label, None when its inner folds
        could not be fitted: it predicts with the geometry), 'position_mm' and 'rotation_mrad' of its
        choice on its held-out unit
    nested : dict or None, the outer folds' held-out means of their own choices ('position_mm',
        'rotation_mrad'), the geometry's ('geometric_position_mm'), 'agree' (folds that chose ``best``) and
        'needed'; None when no fold could choose
    """

    fit: PoseFit
    table: list
    chosen: str
    seconds: float
    best: str = ""
    folds: tuple = ()
    nested: dict | None = None


def fold_fits(cands: list, train: list, nominal: RobotModel, robust: bool) -> list:
    """Every candidate fitted on ``train`` alone (its map's knots over their angles), each started from the
    previous one's fit of the same sessions (the first from the nominal robot): nothing outside ``train``
    reaches them.

    Returns
    -------
    list of PoseFit, one per candidate
    """
    out, prev = [], None
    for c in cands:
        prev = fit_poses(train, nominal, c.extension, covering(c.joint_map, train), robust=robust, warm=prev)
        out.append(prev)
    return out


def held_out(fit: PoseFit, held) -> tuple[float, float]:
    """Mean held-out position (mm) and rotation (rad) errors of a fold's fit registered on ``held``
    (:func:`half_scores`)."""
    p, r = half_scores(fit.model, held)
    return float(p.mean()), float(r.mean())


def score(pos: float, rot: float, ref: PoseFit) -> float:
    """``--extend auto``'s score: held-out position mean / sigma_pos + rotation mean / sigma_rot, the noise
    levels of the geometric fit ``ref``."""
    return pos / ref.sigma_pos + rot / ref.sigma_rot


def nested_choices(cands: list, units: list, geo_folds: list, nominal: RobotModel, robust: bool) -> list:
    """Each outer fold's choice of candidate from its training units alone: a leave-one-out over them (fit
    on the others, score the one left out; one training session: over its three blocks of rows,
    :func:`folds`), scored as the whole table is, against the fold's own geometric fit ``geo_folds[k]``.
    The candidates fitted on some units serve every outer fold that trains on exactly those.

    Returns
    -------
    list of str or None per outer fold (None: an inner fold could not be fitted)
    """
    fitted: dict = {}

    def errors_on(train: list, held) -> list:  # per candidate, (position, rotation) on ``held``
        key = tuple(u.name for u in train)
        if key not in fitted:
            fitted[key] = fold_fits(cands, train, nominal, robust)
        return [held_out(f, held) for f in fitted[key]]

    out = []
    for k in range(len(units)):
        inner = folds([u for j, u in enumerate(units) if j != k])
        try:
            per_held = [errors_on([u for j, u in enumerate(inner) if j != i], h) for i, h in enumerate(inner)]
            scores = np.mean([[score(p, r, geo_folds[k]) for p, r in e] for e in per_held], 0)
            out.append(cands[int(np.argmin(scores))].label)
        except IdentificationError:
            out.append(None)
    return out


def extend_auto(sessions: list, nominal: RobotModel, robust: bool = True) -> AutoResult:
    """Fit every :func:`candidates` model on all sessions, cross-validate each, choose inside each outer fold
    too, and keep the best when the folds agree (module docstring)."""
    t0 = time.perf_counter()
    units = folds(sessions)
    split = len(sessions) == 1
    cands = candidates(nominal, sessions)
    per_fold = [
        fold_fits(cands, [u for j, u in enumerate(units) if j != k], nominal, robust)
        for k in range(len(units))
    ]
    fits, table, prev, outer = {}, [], None, {}
    for ci, c in enumerate(cands):
        full = fit_poses(
            units if split else sessions, nominal, c.extension, c.joint_map, robust=robust, warm=prev
        )
        prev = full
        outer[c.label] = [held_out(per_fold[k][ci], held) for k, held in enumerate(units)]
        fits[c.label] = full
        table.append(
            {
                "label": c.label,
                "position_mm": float(np.mean([p for p, _ in outer[c.label]])),
                "rotation_mrad": 1e3 * float(np.mean([r for _, r in outer[c.label]])),
                "train_position_mm": float(np.mean(np.concatenate([e[0] for e in full.errors.values()]))),
            }
        )
    ref = fits[table[0]["label"]]
    for row in table:
        row["score"] = score(row["position_mm"], row["rotation_mrad"] * 1e-3, ref)
    best = min(table, key=lambda r: r["score"])["label"]
    choices = nested_choices(cands, units, [f[0] for f in per_fold], nominal, robust)
    fold_rows, nested = [], None
    if any(ch is not None for ch in choices):
        for k, (held, ch) in enumerate(zip(units, choices)):
            p, r = outer[ch or cands[0].label][k]
            fold_rows.append({"held": held.name, "chose": ch, "position_mm": p, "rotation_mrad": 1e3 * r})
        fitted = [ch for ch in choices if ch is not None]
        nested = {
            "position_mm": float(np.mean([f["position_mm"] for f in fold_rows])),
            "rotation_mrad": float(np.mean([f["rotation_mrad"] for f in fold_rows])),
            "geometric_position_mm": table[0]["position_mm"],
            "agree": sum(ch == best for ch in fitted),
            "needed": max(len(fitted) - AGREE_ALL_BUT, 1),
        }
    agreed = nested is None or nested["agree"] >= nested["needed"]
    kept = best if agreed else cands[0].label
    chosen = fits[kept]
    if split:  # the blocks were fitted as sessions of their own: refit the whole session once
        chosen = fit_poses(sessions, nominal, chosen.effects[0], chosen.effects[1], robust=robust)
    return AutoResult(chosen, table, kept, time.perf_counter() - t0, best, tuple(fold_rows), nested)
