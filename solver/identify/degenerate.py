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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.identify.lsq import RANK_RTOL, Identifiability

STILL_RAD = 1e-6  # a joint whose range over the session is below this never moves
_COMPONENT_TOL = 1e-6  # singular values of a null-space block below this: no component there


@dataclass(frozen=True)
class Deficiency:
    """One group of parameters the data cannot identify.

    Attributes
    ----------
    combination : str, e.g. "joint 4's axis direction"
    fix : str, the data that would identify it, e.g. "vary joint 4 (it never moves in this session)"
    directions : int, unidentifiable directions it accounts for
    parameters : tuple of str, the parameter names of the group
    """

    combination: str
    fix: str
    directions: int
    parameters: tuple

    def __str__(self) -> str:
        return f"{self.combination} ({self.fix})"


def _groups(names: list, joint_names: tuple, q: np.ndarray) -> list[tuple[str, str, list[int], bool]]:
    """Physical parameter groups: (combination, fix, parameter indices, joint never moves), in chain order."""
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
            still = bool(ranges[j] < STILL_RAD)
            what = f"joint {j + 1}'s axis {kind}" if kind else f"joint {j + 1}'s {head}"
            fix = (
                f"vary joint {j + 1}: it never moves in this session"
                if still
                else f"vary joint {j + 1} in more combinations with the other joints "
                f"(it moves {np.degrees(ranges[j]):.3g} deg here)"
            )
            groups.append((what, fix, idx, still))
        elif head == "laser":
            fix = "tilt the beam more: aim at each point with varied flange orientations"
            groups.append(("the laser direction", fix, idx, False))
        elif head == "M":
            groups.append(
                ("the aperture position", "aim at each point with more varied beam tilts", idx, False)
            )
        else:
            groups.append((f"{head}", "capture more varied configurations", idx, False))
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
    N = _restrict(N, list(held))
    groups = _groups(names, tuple(joint_names), np.asarray(q).reshape(-1, len(joint_names)))
    out = []
    while N.shape[1]:
        removed = [_components(N, g[2]) for g in groups]
        best_i = min(range(len(groups)), key=lambda i: (-removed[i], not groups[i][3], i))
        best, k = groups[best_i], removed[best_i]
        if k == 0:  # no group carries the rest (cannot happen: the groups cover every parameter)
            break
        out.append(Deficiency(best[0], best[1], k, tuple(names[i] for i in best[2])))
        N = _restrict(N, best[2])
        groups = [g for g in groups if g is not best]
    return out


def laser_gauge(names: list, laser_dir: np.ndarray) -> list[int]:
    """The aperture component held to fix the laser gauge: the one along which the beam points most."""
    axis = int(np.argmax(np.abs(laser_dir)))
    return [names.index(f"M.{'xyz'[axis]}")]
