"""The capture check: what the nominal model says about a new capture (where its beam lands, whether the
pose resembles an earlier one), and the lines that tell the operator, with each point's progress."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.model import RobotModel


@dataclass(frozen=True)
class Check:
    """What the nominal model says about one capture.

    Attributes
    ----------
    point : str, the point the operator was asked for
    offset : (2,) array, nominal spot minus the point, mm (NaN when the beam points away from the plane)
    nearest : str, the reference point nearest to the nominal spot
    flag : str, why the capture looks wrong ('' when it looks right)
    similar_to : int or None, 1-based number (at this point) of the most similar earlier capture
    distance : float, its joint-space distance, rad
    vary : tuple of int, 1-based joints whose spread over this point's captures is smallest
    aim : (2,) array or None, the spot the coach planned off the point (layout frame, mm): ``offset`` is
        then measured from it, not from the point
    """

    point: str
    offset: np.ndarray
    nearest: str
    flag: str
    similar_to: int | None
    distance: float
    vary: tuple
    aim: np.ndarray | None = None

    @property
    def target(self) -> str:
        """What ``offset`` is measured from, in words: the point, or the aim the coach planned."""
        if self.aim is None:
            return self.point
        return f"the aim ({self.aim[0]:.0f}, {self.aim[1]:.0f}) mm on the sheet"


def check_capture(
    nominal: RobotModel,
    points: dict,
    name: str,
    q: np.ndarray,
    earlier: np.ndarray,
    opts,
    aim: tuple | None = None,
) -> Check:
    """The nominal-model check and the pose-diversity hint of a new capture.

    Parameters
    ----------
    nominal : RobotModel
    points : dict name -> (3,) array, mm
    name : str, the point the operator was asked for
    q : (n,) array, the captured configuration, rad
    earlier : (k, n) array, earlier captures at this point, rad
    opts : CaptureOptions
    aim : ((2,) array, (3,) array) or None, the spot the coach planned in the point's cell (layout frame,
        base frame; mm): the beam is checked against it (``--aim anywhere``), not against the point
    """
    p = points[name] if aim is None else aim[1]
    spot, length = predict_spots(nominal, q[None], p[2])
    mark = None if aim is None else np.asarray(aim[0], dtype=float)
    if length[0] <= 0:
        return Check(
            name,
            np.full(2, np.nan),
            "",
            "the nominal beam points away from the table",
            None,
            np.nan,
            (),
            mark,
        )
    offset = spot[0, :2] - p[:2]
    others = {**points, name: p}
    nearest = min(others, key=lambda k: np.linalg.norm(spot[0, :2] - others[k][:2]))
    flag = ""
    where = name if aim is None else "the aim"
    # within check_mm of its point the spot is the nominal model's error, even nearer another point (crosses
    # on a printed sheet lie 40-50 mm apart); beyond it, the nearer point names the likely mistake
    if np.linalg.norm(offset) > opts.check_mm and nearest != name:
        flag = f"the beam lands nearest to {nearest}, not {where}: aimed at the wrong point?"
    elif np.linalg.norm(offset) > opts.check_mm:
        flag = (
            f"{np.linalg.norm(offset):.0f} mm from {where} by the nominal model (more than "
            f"{opts.check_mm:g} mm): aimed at the wrong place, or the arm moved?"
        )
    similar_to, distance, vary = None, np.nan, ()
    if len(earlier):
        d = np.linalg.norm(earlier - q, axis=1)
        k = int(np.argmin(d))
        distance = float(d[k])
        if distance < opts.similar_rad:
            similar_to = k + 1
            spread = np.vstack([earlier, q]).std(axis=0) / np.ptp(nominal.limits, axis=1)
            vary = tuple(int(j) + 1 for j in np.argsort(spread)[:2])
    return Check(name, offset, nearest, flag, similar_to, distance, vary, mark)


def progress_lines(counts: dict, per_point: int, width: int = 20) -> list[str]:
    """One progress bar per point: done and left."""
    out = []
    for nm, k in counts.items():
        full = round(width * min(k, per_point) / per_point)
        out.append(
            f"  {nm:<6} [{'#' * full}{'-' * (width - full)}] {k:3d}/{per_point}  {max(per_point - k, 0):3d} "
            "left"
        )
    return out


def report_lines(check: Check, number: int, t: float, peak: float, length: float | None) -> list[str]:
    """The lines that report a capture: when and how still it was taken, the nominal model's check, a flag,
    a similar earlier pose."""
    lines = [
        f"captured {check.point} #{number} at t = {t:.1f} s (still, max |dq| {peak:.4f} rad/s)"
        + (f", laser length {length:.1f} mm" if length is not None else "")
    ]
    if np.all(np.isfinite(check.offset)):
        dx, dy = check.offset
        lines.append(
            f"  nominal model: the beam lands {np.hypot(dx, dy):.1f} mm from {check.target} (dx {dx:+.1f}, "
            f"dy {dy:+.1f} mm)"
        )
    if check.flag:
        lines.append(f"  ! {check.flag} -- discard it?")
    if check.similar_to is not None:
        joints = " and ".join(str(j) for j in check.vary)
        lines.append(
            f"  ~ similar to capture #{check.similar_to} at {check.point} (joint distance "
            f"{check.distance:.2f} rad): "
            f"vary joints {joints} for the next ones"
        )
    return lines
