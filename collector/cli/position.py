"""Position-session pieces of ``lasercal simulate`` and ``lasercal predict`` (called from cli/solve.py)."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.solver.analysis.simulate import random_configs, simulate_positions
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.data import truth_references
from lasercal.solver.formats.positions import position_meta, write_position_session
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_configs
from lasercal.solver.identify.position import sensor_points, target_start
from lasercal.solver.kinematics.effects import extension_from_model
from lasercal.solver.kinematics.gravity import model_torques
from lasercal.solver.kinematics.model import RobotModel

SENSOR_DISTANCE = 2500.0  # mm: a tracker's usual stand-off from the robot base
TARGET_OFFSETS = np.array([[60.0, 0, 30], [-40, 50, 20], [0, -60, 40], [50, 50, 60]])  # mm, tip frame


def default_sensor(distance: float = SENSOR_DISTANCE) -> np.ndarray:
    """^S T_base (4, 4): the sensor ``distance`` mm from the base, rotated 40, 10, -20 deg (z, y, x)."""
    X = np.eye(4)
    X[:3, :3] = Rotation.from_euler("zyx", [40, 10, -20], degrees=True).as_matrix()
    X[:3, 3] = distance * np.array([0.8, -0.5, 0.33]) / np.linalg.norm([0.8, -0.5, 0.33])
    return X


def default_targets(model: RobotModel, k: int) -> dict:
    """k targets at fixed offsets in the tip frame (ee_pose) or around the model's tool point."""
    M = np.asarray(model.ee_pose) if model.ee_pose is not None else np.eye(4)
    base = M[:3, 3] if model.ee_pose is not None else target_start(model)
    return {f"T{i + 1}": base + M[:3, :3] @ TARGET_OFFSETS[i % len(TARGET_OFFSETS)] for i in range(k)}


def cmd_simulate_position(args, truth_path: Path, effect) -> int:
    """``lasercal simulate TRUTH --measurement position``: random in-limit poses, every target each pose."""
    chain = {k: v for k, v in (("base_link", args.base_link), ("tip_link", args.tip_link)) if v}
    truth = load_model(truth_path, **chain)
    truth_ref, nominal = truth_references(truth_path, args.output, args.robot)  # relative to the session
    if not truth.targets:
        truth = truth.replace(targets=default_targets(truth, args.targets))
    if truth.sensor_pose is None:
        truth = truth.replace(sensor_pose=default_sensor())
    rng = np.random.default_rng(args.seed)
    names = np.array(list(truth.targets), dtype=object)
    q = np.repeat(random_configs(truth, args.configs, rng), len(names), axis=0)
    tg = np.tile(names, args.configs)
    tau, src = model_torques(truth, q)
    y = simulate_positions(truth, q, tg, args.noise, rng, effect, tau)
    sim = {"truth": truth_ref, "noise_mm": args.noise, "seed": args.seed, "torques": src}
    if effect is not None:
        sim["effect"] = {"name": effect.effect, **effect.to_dict()}
    meta = position_meta(nominal, names, **chain, noise_mm=args.noise, simulated=sim)
    write_position_session(args.output, meta, q, y, tg)
    print(
        f"wrote {args.output}: {args.configs} poses x {len(names)} targets (truth {truth.name}, sensor "
        f"{np.linalg.norm(truth.sensor_pose[:3, 3]):.0f} mm from the base, noise {args.noise} mm)"
    )
    return 0


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
    ext = extension_from_model(model.extensions, args.model, model.n)
    if ext is not None:
        if "tau" in ext.needs() and tau is None:
            tau = model_torques(model, q)[0]
        if "t" in ext.needs() and t is None:
            raise FormatError(
                args.configs, f"the {ext.effect} extension needs a 't' column (s)", line=1, field="t"
            )
        q = ext.true_q(q, t, tau)
    w = csv.writer(sys.stdout, lineterminator="\n")
    w.writerow(header + ["x", "y", "z"])
    for row, p in zip(rows, sensor_points(model, q, names)):
        w.writerow(row + [f"{c:.6f}" for c in p])
    return 0
