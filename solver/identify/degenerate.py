"""Degenerate fits: the parameter combinations the data cannot identify, named, with the data that would.

The SVD of the column-scaled Jacobian (:func:`solver.identify.lsq.identifiability`) gives the
null space N (p, k): parameter changes no capture can see. One of them is a gauge every laser
session has -- the aperture slides along the beam without moving a spot (thesis Section
3.2.1) -- and is fixed by holding the aperture's component along the beam (p_Mz for a
vertical beam). What is left, N_0 = {v in span(N) : v_held = 0}, is the deficiency: the
model needs rank p - (held) and the data gives less.

Naming. Parameters form physical groups: a joint's axis direction (wx, wy), its axis
position (qx, qy), the laser direction, the aperture, any other named block. Holding a
group g at its start value removes rank(N_0[g]) directions from the deficiency (those with a
component in g). Groups are taken greedily -- most directions removed first; among equals a
joint that never moves in the session, then the upstream group -- and N_0 is restricted to
v_g = 0 after each, until nothing is left. The chosen groups are the smallest set whose
values the data cannot tell, each with the data that would fix it.

With a prior (:mod:`solver.identify.prior`) a direction the data cannot see is held by the
prior, not left undefined: only directions with no prior at all (a sensor frame, identified
points) are deficient. The directions the prior determined (eq. P5: posterior sigma / prior
sigma above :data:`PRIOR_RATIO`) are named the same way, with what they leave uncalibrated
(:func:`determination`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.identify.lsq import RANK_RTOL, Identifiability
from lasercal.solver.kinematics.joint_names import joint_label

STILL_RAD = 1e-6  # a joint whose range over the session is below this never moves
_COMPONENT_TOL = 1e-6  # singular values of a null-space block below this: no component there
PRIOR_RATIO = 0.9  # posterior / prior sigma above this: the prior determined it (data < 1/4 of the info)
DATA_RATIO = 0.5  # below this: the data determined it (data > 3 times the prior's information)


@dataclass(frozen=True)
class Deficiency:
    """One group of parameters the data cannot identify.

    Attributes
    ----------
    combination : str, e.g. "joint 4's axis direction"
    fix : str, the data that would identify it, e.g. "vary joint 4 (it never moves in this session)"
    directions : int, unidentifiable directions it accounts for
    parameters : tuple of str, the parameter names of the group
    affects : str, what stays uncalibrated while it is not identified, e.g. "tool orientation about
        joint 7"
    """

    combination: str
    fix: str
    directions: int
    parameters: tuple
    affects: str = ""

    def __str__(self) -> str:
        return f"{self.combination} ({self.fix})"


def _groups(names: list, joint_names: tuple, q: np.ndarray) -> list[tuple[str, str, list[int], bool, str]]:
    """Physical parameter groups: (combination, fix, parameter indices, joint never moves, what it affects),
    in chain order."""
    ranges = np.ptp(q, axis=0) if len(q) else np.zeros(len(joint_names))
    kinds = {"wx": "direction", "wy": "direction", "vx": "direction", "vy": "direction"}
    kinds |= {"qx": "position", "qy": "position"}
    out: dict[tuple, list[int]] = {}
    for k, nm in enumerate(names):
        head, _, tail = nm.rpartition(".")
        key = (head, kinds.get(tail, "")) if head else (nm, "")
        out.setdefault(key, []).append(k)
    groups = []
    for (head, kind), idx in out.items():
        if head in joint_names:
            j = joint_names.index(head)
            jn = joint_label(j, joint_names)
            still = bool(ranges[j] < STILL_RAD)
            what = f"{jn}'s axis {kind}" if kind else f"{jn}'s {head}"
            fix = (
                f"vary {jn}: it never moves in this session"
                if still
                else f"vary {jn} in more combinations with the other joints "
                f"(it moves {np.degrees(ranges[j]):.3g} deg here)"
            )
            affects = (
                f"tool orientation about axes across {jn}'s"
                if kind == "direction"
                else f"positions swept by {jn} (its axis's offset)"
            )
            groups.append((what, fix, idx, still, affects + " uncalibrated"))
        elif head == "laser":
            fix = "tilt the beam more: aim at each point with varied flange orientations"
            groups.append(("the laser direction", fix, idx, False, "the beam's direction uncalibrated"))
        elif head == "M":
            fix = "aim at each point with more varied beam tilts"
            groups.append(("the aperture position", fix, idx, False, "where the beam starts uncalibrated"))
        else:
            fix = "capture more varied configurations"
            groups.append((f"{head}", fix, idx, False, f"{head} uncalibrated"))
    return groups


def _restrict(N: np.ndarray, rows: list[int]) -> np.ndarray:
    """Orthonormal basis (in the coefficients of N's columns) of span(N) with the components ``rows`` zero."""
    if N.shape[1] == 0 or not rows:
        return N
    _, s, Vt = np.linalg.svd(N[rows], full_matrices=True)
    r = int(np.sum(s > _COMPONENT_TOL))
    return N @ Vt[r:].T


def _components(N: np.ndarray, rows: list[int]) -> int:
    """Directions of span(N) with a component in ``rows``: rank(N[rows])."""
    return int(np.sum(np.linalg.svd(N[rows], compute_uv=False) > _COMPONENT_TOL))


def deficiencies(
    idf: Identifiability, names: list, joint_names: tuple, q: np.ndarray, held: list[int] = ()
) -> list[Deficiency]:
    """The unidentifiable combinations beyond the gauge, as named parameter groups (module docstring).

    Parameters
    ----------
    idf : Identifiability, with its null space (p, p - rank) in parameter units
    names : list of p str, the parameter names (``joint.wx`` ... as the identifications name them)
    joint_names : tuple of n str, the model's joints
    q : (m, n) array, the session's configurations, rad (which joints never move)
    held : parameter indices that fix the gauge (e.g. the aperture along the beam)

    Returns
    -------
    list of Deficiency, empty when the data identify everything the model needs
    """
    N = idf.null_space / np.linalg.norm(idf.null_space, axis=0).clip(RANK_RTOL)
    return name_directions(_restrict(N, list(held)), names, joint_names, q)


def name_directions(
    N: np.ndarray, names: list, joint_names: tuple, q: np.ndarray, tol: float = _COMPONENT_TOL
) -> list[Deficiency]:
    """The smallest set of parameter groups that carries the directions N (p, k) (module docstring).

    Parameters
    ----------
    N : (p, k) array, directions in parameter space
    names, joint_names, q : as :func:`deficiencies`
    tol : float, singular values of a group's block of N below this: the group has no component there
        (exact null spaces: round-off; directions a prior holds are never exactly sparse, so a share:
        then among groups removing as many directions the one with the larger share goes first)

    Returns
    -------
    list of Deficiency
    """
    groups = _groups(names, tuple(joint_names), np.asarray(q).reshape(-1, len(joint_names)))
    out = []
    while N.shape[1]:
        sv = [np.linalg.svd(N[g[2]], compute_uv=False) for g in groups]
        removed = [int(np.sum(v > tol)) for v in sv]
        weight = [float(np.sum(v**2)) if tol > _COMPONENT_TOL else 0.0 for v in sv]
        best_i = min(range(len(groups)), key=lambda i: (-removed[i], -weight[i], not groups[i][3], i))
        best, k = groups[best_i], removed[best_i]
        if k == 0:  # no group carries the rest (cannot happen: the groups cover every parameter)
            break
        out.append(Deficiency(best[0], best[1], k, tuple(names[i] for i in best[2]), best[4]))
        N = _restrict(N, best[2])
        groups = [g for g in groups if g is not best]
    return out


@dataclass(frozen=True)
class Determination:
    """Which combinations the data determined and which the prior did (eq. P5 of solver.identify.prior).

    Attributes
    ----------
    ratios : (k,) array, posterior sigma / prior sigma of each eigen-direction of the prior-scaled
        posterior covariance (parameters with a prior), ascending
    data, both, prior : int, directions with ratio < DATA_RATIO, in between, > PRIOR_RATIO
    from_prior : tuple of Deficiency, the prior-determined directions named as parameter groups
    """

    ratios: np.ndarray
    data: int
    both: int
    prior: int
    from_prior: tuple

    def as_dict(self) -> dict:
        """The model file's and the report's ``identification.determined_by`` mapping."""
        return {
            "data": self.data,
            "data_and_prior": self.both,
            "prior": self.prior,
            "thresholds": {"data_below": DATA_RATIO, "prior_above": PRIOR_RATIO},
            "ratios": [round(float(r), 4) for r in self.ratios],
            "from_prior": [
                {"combination": d.combination, "directions": d.directions, "affects": d.affects, "fix": d.fix}
                for d in self.from_prior
            ],
        }


_SHARE = 0.3  # a group holding less than 0.3^2 = 9 % of a prior-held direction (prior units) is not named


def determination(
    cov: np.ndarray, L: np.ndarray, rows: np.ndarray, names: list, joint_names: tuple, q, held: list[int] = ()
) -> Determination:
    """Data or prior, per combination (eq. P5): eigen-directions of L C L^T, L the prior's whitening.

    Parameters
    ----------
    cov : (p, p) array, the posterior covariance (eq. P4)
    L : (k, p) array, the prior's whitening (:attr:`solver.identify.prior.Prior.whitening`)
    rows : (k,) int array, the parameter each row of L belongs to (parameters without a prior have none)
    names, joint_names, q : as :func:`deficiencies`
    held : parameter indices of a gauge, fixed by convention rather than by data or prior (left out)

    Returns
    -------
    Determination
    """
    keep = ~np.isin(rows, list(held))
    L, rows = L[keep], rows[keep]
    lam, U = np.linalg.eigh(L @ cov @ L.T)
    ratios = np.sqrt(np.clip(lam, 0.0, None))
    prior = ratios > PRIOR_RATIO
    N = np.zeros((len(names), int(prior.sum())))
    N[rows] = U[:, prior]  # whitened: each row in units of its tolerance, comparable across mm and rad
    return Determination(
        ratios,
        int(np.sum(ratios < DATA_RATIO)),
        int(np.sum((ratios >= DATA_RATIO) & ~prior)),
        int(prior.sum()),
        tuple(name_directions(N, names, joint_names, q, _SHARE)),
    )


def laser_gauge(names: list, laser_dir: np.ndarray) -> list[int]:
    """The aperture component held to fix the laser gauge: the one along which the beam points most."""
    axis = int(np.argmax(np.abs(laser_dir)))
    return [names.index(f"M.{'xyz'[axis]}")]
