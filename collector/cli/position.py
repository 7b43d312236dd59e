"""The position-session piece of ``lasercal predict`` (called from cli/solve.py)."""

from __future__ import annotations

import csv
import sys

import numpy as np

from lasercal.collector.cli.options import parse_payload, unused
from lasercal.solver.control.nominal import gravity_robot
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.session import header_beside, load_configs
from lasercal.solver.identify.position import sensor_points
from lasercal.solver.kinematics.gravity import model_torques
from lasercal.solver.kinematics.joint_map import model_extension
from lasercal.solver.kinematics.model import RobotModel


def cmd_predict_position(model: RobotModel, args) -> int:
    """``lasercal predict`` of a position model: x, y, z in the sensor frame (a row per input row with a
    ``target`` column, else a row per configuration and target)."""
    if model.sensor_pose is None or not model.targets:
        raise FormatError(args.model, "a position model needs 'sensor' and 'targets'", field="sensor")
    cfg = load_configs(args.configs, model)
    if "target" in cfg.header:
        j = cfg.header.index("target")
        names = np.array([r[j].strip() for r in cfg.rows], dtype=object)
        for i, nm in enumerate(names):
            if nm not in model.targets:
                raise FormatError(args.configs, f"unknown target {nm!r}", line=i + 2, field="target")
        rows, q, tau, t = cfg.rows, cfg.q, cfg.tau, cfg.t
        header = cfg.header
    else:
        k = len(model.targets)
        names = np.tile(np.array(list(model.targets), dtype=object), len(cfg.q))
        rows = [r + [nm] for r in cfg.rows for nm in model.targets]
        q = np.repeat(cfg.q, k, axis=0)
        tau = None if cfg.tau is None else np.repeat(cfg.tau, k, axis=0)
        t = None if cfg.t is None else np.repeat(cfg.t, k)
        header = cfg.header + ["target"]
    ext = model_extension(model.extensions, args.model, model.n)  # its joint map too
    if ext is None or "tau" not in ext.needs() or tau is not None:
        unused(args, "no torques are computed: no compliance, or the CSV's", "payload")
    if ext is not None:
        if "tau" in ext.needs() and tau is None:  # the fit's torques
            tau = model_torques(gravity_robot(model, args.model, payload=parse_payload(args.payload)), q)[0]
        if "t" in ext.needs() and t is None:
            raise FormatError(
                args.configs, f"the {ext.effect} extension needs a 't' column (s)", line=1, field="t"
            )
        q = ext.true_q(q, t, tau)
    w = csv.writer(sys.stdout, lineterminator="\n")
    w.writerow(header_beside(header, ["x", "y", "z"]))  # the predicted x, y, z keep their names
    for row, p in zip(rows, sensor_points(model, q, names)):
        w.writerow(row + [f"{c:.6f}" for c in p])
    return 0
