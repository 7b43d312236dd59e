"""lasercal: kinematic calibration of a serial arm, the whole job from Python.

.. code-block:: python

    import lasercal

    lasercal.simulate("panda_thesis_identified", "session", layout="thesis", seed=1)  # or a real session
    cal = lasercal.calibrate(lasercal.load_session("session"), extend="auto")  # = lasercal solve
    print(cal.summary())                        # what lasercal solve prints
    cal.save("model.yaml")                      # the model file lasercal solve writes
    cal.report("report")                        # = lasercal report
    nxt = lasercal.plan(lasercal.load_session("session"), next=10)  # = lasercal plan
    robot = lasercal.load_model("model.yaml")   # a calibrated model, a built-in robot or a URDF
    T = robot.fk(q)                             # (m, 4, 4) mm: the flange where the joints read q (rad)
    sol = robot.ik(goals, seed=q0)              # joint angles (m, n) rad reaching goals (m, 3) mm or (m, 6)
    cmd = robot.correct(q=program)              # commands for a controller that keeps the nominal model
    corrector = lasercal.Corrector(robot, tool=(0, 0, 103.4))  # the same, one goal at a time, at 1 kHz
    found = lasercal.spots(["p1.jpg"], layout="sheet.yaml")  # = lasercal spots

See docs/api.md and docs/use.md. This package is the folder ``collector/api`` (a setuptools package-dir
mapping): the front door belongs to the application, which alone may import solver, vision and the
report; the repository keeps its three folders. Its names load on first use, so that ``import lasercal``
(which ``lasercal --help`` does first) imports nothing else.
"""

from __future__ import annotations

import importlib

_LAZY = {
    "calibrate": "lasercal.calibration",
    "simulate": "lasercal.simulation",
    "plan": "lasercal.planning",
    "spots": "lasercal.photos",
    "calibrate_fullpose": "lasercal.fullpose",
    "FullPoseResult": "lasercal.fullpose",
    "CapturePlan": "lasercal.planning",
    "Simulation": "lasercal.simulation",
    "Calibration": "lasercal.calibration",
    "load_session": "lasercal.solver.formats.session",
    "Session": "lasercal.solver.formats.session",
    "load_model": "lasercal.solver.control.robot",
    "Robot": "lasercal.solver.control.robot",
    "Correction": "lasercal.solver.control.robot",
    "Corrector": "lasercal.solver.control.corrector",
    "Tool": "lasercal.solver.control.tools",
    "IKOptions": "lasercal.solver.kinematics.ik",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # once loaded, a plain attribute
        return value
    raise AttributeError(f"module 'lasercal' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
