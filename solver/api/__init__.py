"""lasercal: kinematic calibration of a serial arm, and the Python API to use a calibration.

.. code-block:: python

    import lasercal

    robot = lasercal.load_model("model.yaml")   # a calibrated model, a built-in robot or a URDF
    T = robot.fk(q)                             # (m, 4, 4) mm: the flange where the joints read q (rad)
    sol = robot.ik(goals, seed=q0)              # joint angles (m, n) rad reaching goals (m, 3) mm or (m, 6)
    cmd = robot.correct(q=program)              # commands for a controller that keeps the nominal model

See :mod:`lasercal.solver.control.robot` and docs/use.md. This package is the folder ``solver/api`` (a
setuptools package-dir mapping): the repository keeps its three folders. Its names load on first use,
so that ``import lasercal`` (which ``lasercal --help`` does first) imports nothing else.
"""

from __future__ import annotations

import importlib

_LAZY = {
    "load_model": "lasercal.solver.control.robot",
    "Robot": "lasercal.solver.control.robot",
    "Correction": "lasercal.solver.control.robot",
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
