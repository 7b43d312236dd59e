"""``lasercal.plan``: the next captures that most lower the predicted error where the robot is used.

The posterior of the session's captures so far under its prior (:func:`~lasercal.solver.analysis.design.
posterior`), and the greedy design of the capture coach (:class:`~lasercal.solver.analysis.design.Coach`,
eqs. D1-D6 of :mod:`solver.analysis.design`): what ``lasercal plan`` prints and writes.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: numpy and the solver load when a plan is made
    import numpy as np

    from lasercal.solver.analysis.design import Plan, Status

MIN_SHEET_CAPTURES = 9  # captures from which a sheet session's own fit places the sheet (else its placement)


@dataclass(frozen=True)
class CapturePlan:
    """The next captures of a session and the error predicted where the robot is used.

    Attributes
    ----------
    captures : int, the session's captures so far
    status : Status, the coach's verdict: rank of the identifiable combinations, predicted error (mm) and
        its uncertainty at ``status.region``
    plan : Plan, the next captures (point, q (K, n) rad, expected error after each, mm)
    sigma : float, the posterior's noise estimate, mm
    n : int, the robot's joints
    aims : (K, 2) array or None, a camera session planned anywhere (``--aim anywhere``): where each spot
        should land, the layout's frame, mm
    """

    captures: int
    status: Status
    plan: Plan
    sigma: float
    n: int
    aims: np.ndarray | None = None

    @property
    def header(self) -> list[str]:
        """The CSV's columns: point, q1..qN (rad), expected_mm (aim_x, aim_y, mm: when planned anywhere)."""
        aim = ["aim_x", "aim_y"] if self.aims is not None else []
        return ["point"] + [f"q{i}" for i in range(1, self.n + 1)] + ["expected_mm"] + aim

    @property
    def rows(self) -> list[list[str]]:
        """The next captures as CSV cells (q to 1e-6 rad, the expected error to 1e-4 mm, aims to 0.1 mm)."""
        p = self.plan
        aims = [[f"{a:.1f}" for a in xy] for xy in self.aims] if self.aims is not None else [[]] * len(p.q)
        return [
            [str(nm)] + [f"{a:.6f}" for a in q] + [f"{e:.4f}"] + xy
            for nm, q, e, xy in zip(p.point, p.q, p.expected, aims)
        ]

    def csv(self) -> str:
        """The CSV ``lasercal plan`` prints (rows end in LF)."""
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows([self.header] + self.rows)
        return buf.getvalue()

    def save(self, path) -> Path:
        """Write the CSV to ``path`` (replaced if it exists), as Python's csv module writes a file (rows end
        in CR LF)."""
        with open(path, "w", newline="") as f:
            csv.writer(f).writerows([self.header] + self.rows)
        return Path(path)

    def as_dict(self) -> dict:
        """The JSON object ``lasercal plan --json`` prints."""
        st = self.status
        return {
            "captures": self.captures,
            "identifiable": {"rank": st.rank, "of": st.n_identifiable, "parameters": st.n_params},
            "region": st.region,
            "predicted_mm": round(st.predicted, 4),
            "uncertainty_mm": round(st.uncertainty, 4),
            "sigma_mm": round(self.sigma, 4),
            "next": [dict(zip(self.header, r)) for r in self.rows],
        }

    def to_json(self) -> str:
        return json.dumps(self.as_dict(), indent=2)

    def summary(self) -> str:
        """One line: captures, identifiable rank, the predicted error at the use region."""
        from lasercal.collector.report.text import identifiable_text

        st = self.status
        return (
            f"{self.captures} captures; {identifiable_text(st.rank, st.n_params, st.n_identifiable)}; "
            f"predicted error at {st.region}: {st.predicted:.2f} ± {st.uncertainty:.2f} mm"
        )


def plan(
    session, *, next: int = 10, layout=None, workspace=None, aim_noise: float | None = None, seed: int = 0
) -> CapturePlan:
    """The next ``next`` captures that most lower the predicted error where the robot is used.

    Parameters
    ----------
    session : Session (:func:`lasercal.load_session`; no captures yet is fine) or a session folder
    next : int, captures to plan
    layout : str or Path, a layout YAML (default: the points, calibration and validation lists of the
        session); its aiming hints (tilt, length) constrain the captures
    workspace : ((3,), (3,)) mm, a box (min corner, max corner) where the robot is used, in place of the
        layout's validation points
    aim_noise : float, the operator's expected aiming noise per axis, mm (default the prior's
        ``noise_mm.laser``)
    seed : int, seed of the candidate sampling

    Returns
    -------
    CapturePlan

    Raises
    ------
    DesignError
        A session that is not a laser session, or one without a prior (``prior='none'``).
    """
    import numpy as np

    from lasercal.collector.sessions.anywhere import CAMERA_NOISE_MM, cells, session_layout_file
    from lasercal.solver.analysis.design import Coach, DesignError, posterior
    from lasercal.solver.formats.session import load_layout, load_session, session_layout
    from lasercal.solver.identify.spot import identify_lm, in_base_frame

    if not hasattr(session, "measurement"):
        session = load_session(session)
    if session.measurement != "laser":
        raise DesignError("plan designs laser sessions (spot on a plane), not point sessions")
    # the session's own layout keeps its aiming hints (tilt, length), which the constraints obey
    layout = load_layout(layout) if layout else session_layout(session.meta, session.path)
    sheet = session.frame == "sheet"
    if sheet:  # the sheet where the captures so far put it (or its stated placement)
        pose = identify_lm(session).model.sheet if session.m >= MIN_SHEET_CAPTURES else layout.sheet
        layout = layout.in_base(pose)
        session = in_base_frame(session, pose)  # (a pose is known: in_base refused the layout without one)
    nominal = session.robot
    if session.aperture_z is not None:
        nominal = nominal.replace(aperture=np.r_[nominal.aperture[:2], session.aperture_z])
    if session.tolerances is None:
        raise DesignError("plan predicts from a prior: --prior none leaves no prediction to make")
    tol = session.tolerances
    # a camera session: its measured captures at the camera's noise (as capture's coach fits them); one the
    # camera could not measure is left out of the fit (it still keeps its pose from being suggested again)
    use = session.measured if session.spot_sigma is not None and session.measured.any() else None
    if aim_noise is not None or use is not None:
        tol = tol.with_noise("laser", aim_noise if aim_noise is not None else CAMERA_NOISE_MM)
    use = np.ones(session.m, bool) if use is None else use
    post = posterior(nominal, session.q[use], session.target[use], tol, sheet=pose if sheet else None)
    anywhere = None
    if sheet and (session.meta.get("collector") or {}).get("aim") == "anywhere":  # spots planned anywhere
        layout_file = session_layout_file(session.meta.get("collector") or {}, session.path)
        spots = cells(session_layout(session.meta, session.path), layout_file)
        anywhere = {k: pose.to_base(v, layout.plane_z) for k, v in spots.items()}
    coach = Coach(
        nominal,
        layout,
        seed,
        tol,
        workspace=workspace,
        model=post.model,
        lookahead=next,
        sheet=sheet,
        anywhere=anywhere,
        pose=pose if sheet else None,
    )
    coach.post = post
    points = np.array([layout.points[p] for p in session.point]).reshape(-1, 3)
    st = coach.status(session.q, target=points)  # no suggestion near a capture at its point
    aims = pose.from_base(st.plan.target) if anywhere is not None else None
    return CapturePlan(session.m, st, st.plan, post.sigma, nominal.n, aims)
