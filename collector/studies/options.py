"""The MUKCa study's settings, apart from the study itself so that ``lasercal study-mukca --help`` shows
them without loading the solver."""

from __future__ import annotations

from dataclasses import dataclass

from lasercal.solver.analysis import ALPHA

ROBOTS = ("panda_1", "panda_2", "panda_3", "panda_4")
# Franka hand (0.73 kg) plus ball tool (~0.1 kg); centre of mass ~60 mm below the flange at q = 0 (mm).
PAYLOAD = (0.83, (88.0, 0.0, 866.0))


@dataclass(frozen=True)
class StudyOptions:
    """Study settings.

    Attributes
    ----------
    bootstrap : int, first-order simulated replicates (diagnosis bootstrap and simulation check)
    refits : int, full nonlinear re-simulations with refits (residual RMS the experiment should show)
    alpha : float, family-wise significance level
    seed : int
    payload : (kg, (3,) mm at q = 0), hand and tool for the gravity model
    jobs : int, robots studied at once in separate processes (0: one per CPU core; the robots
        are independent, each with its own seeded generator, so the report is the same)
    prior : str or None, the prior of every fit (``--prior``: None the robot's tolerances, 'none' plain
        least squares, or a lasercal-prior/1 file)
    """

    bootstrap: int = 2000
    refits: int = 5
    alpha: float = ALPHA
    seed: int = 0
    payload: tuple = PAYLOAD
    jobs: int = 0
    prior: str | None = None


QUICK = StudyOptions(bootstrap=200, refits=2)
