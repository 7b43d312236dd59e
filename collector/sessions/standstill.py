"""Standstill: waiting until the arm is still before a capture, and checking it stayed still while
photographed (capture and validation sessions)."""

from __future__ import annotations

import numpy as np

from lasercal.collector.hardware.base import FakeClock, JointState, RobotAdapter
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.model import RobotModel

# mm: the most the spot may move (under the nominal model) from the standstill read the row logs to a read
# after its photo: a tenth of a measured spot's noise (0.02-0.05 mm). An arm that creeps more (a real-time
# arm still settling: franky-sim's moved it 0.04 mm under load) is photographed again after a new standstill.
PHOTO_MOVED_MM = 0.005
PHOTO_TRIES = 3


def moved_during_photo(robot: RobotAdapter, still: JointState, model: RobotModel, plane_z: float) -> float:
    """How far (mm) the spot moved on the plane ``plane_z`` under ``model`` from the standstill read ``still``
    to a read after the photo; 0 for an arm on a simulated clock, which cannot move while nothing sleeps
    (and whose reads draw its noise)."""
    if isinstance(robot.clock, FakeClock):
        return 0.0
    spots = predict_spots(model, np.array([still.q, robot.read().q]), plane_z)[0]
    return float(np.linalg.norm(spots[1] - spots[0]))


def wait_still(
    robot: RobotAdapter, threshold: float, hold: float, timeout: float, poll: float, tick=None
) -> tuple[JointState | None, float]:
    """Poll the arm until every joint has been slower than ``threshold`` (rad/s) for ``hold`` s.

    Parameters
    ----------
    robot : RobotAdapter
    threshold : float, rad/s
    hold : float, s
    timeout : float, give up after this long, s
    poll : float, interval between reads, s
    tick : callable(peak, held) or None, told after every read: the largest joint speed (rad/s) and how long
        the arm has been still (s), for a countdown

    Returns
    -------
    state : the reading that completed the hold, or None after ``still_timeout``
    peak : float, largest joint speed of the last reading, rad/s
    """
    clock = robot.clock
    start = clock.now()
    since = None
    while True:
        s = robot.read()
        peak = float(np.abs(s.dq).max())
        if peak < threshold:
            since = s.t if since is None else since
            if s.t - since >= hold:
                return s, peak
        else:
            since = None
        if tick is not None:
            tick(peak, 0.0 if since is None else s.t - since)
        if s.t - start > timeout:
            return None, peak
        clock.sleep(poll)
