"""Issue 23's sheet check: a printed sheet laid down anywhere, its pose identified with the robot.

Run: python benchmarks/bench_sheet_pose.py [SEEDS]   (default 8 seeds per layout; prints numbers)

Truth: the thesis's identified Panda in its own frame (eq. S2: joint 1 as the nominal's; the table, normal
to joint 1, at z = -8 mm), 0.5 mm aiming noise. Per seed and layout (the thesis's P1-P3 with 15 captures
each, and a 3 x 3 grid with 5 each), the sheet lies displaced by up to +-30 mm and +-10 deg from where
the layout says. Two fits of the same captures (solve's MAP estimator):

* sheet: the session says ``frame: sheet`` (points in the sheet's frame, the layout's placement), the
  sheet's pose identified with the robot;
* base: the true base-frame points are given (what a laser tracker would have measured).

Held-out error: where the fitted and the true beams meet planes z = -8, 100 and 250 mm (base frame) for
configurations off the table (aimed by the true robot at points spread over x 300..650, y -300..300 mm).
Then the 5 mm / -3 mm / 1.5 deg case of issue 23 before (today's reading: the layout's points taken as
base-frame points) and after.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.errors import AimingError
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Layout, Session, load_layout
from lasercal.solver.identify.spot import identify_lm, predict_spots
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.frames import moved, own_frame
from lasercal.solver.kinematics.poe import fk
from lasercal.solver.kinematics.sheet import SheetPose

NOMINAL = load_model("panda")
TRUTH = moved(
    load_model("panda_thesis_identified"), own_frame(load_model("panda_thesis_identified"), NOMINAL)
)
NOISE = 0.5
PLANES = (-8.0, 100.0, 250.0)
THESIS = load_layout("thesis")
GRID = Layout(
    "grid 3x3", -8.0,
    {f"G{i}{j}": np.array([400.0 + 100 * i, -150.0 + 150 * j, -8.0]) for i in range(3) for j in range(3)},
    tuple(f"G{i}{j}" for i in range(3) for j in range(3)), (), dict(THESIS.aiming),
)  # fmt: skip


def as_sheet(layout: Layout) -> Layout:
    """A base layout read as a sheet: its x, y become sheet coordinates, placed where the layout says."""
    pts = {k: np.r_[v[:2], 0.0] for k, v in layout.points.items()}
    return replace(layout, points=pts, frame="sheet", sheet=SheetPose())


def session(layout: Layout, c, frame: str) -> Session:
    """The captures as a sheet session (the layout's sheet coordinates) or a base one (as given)."""
    target = np.array([layout.points[p] for p in c.point])
    if frame == "sheet":
        target[:, 2] = layout.plane_z
    m = len(c.q)
    return Session(
        Path("."), {}, NOMINAL, layout.plane_z, TRUTH.aperture[2], layout.points, c.point, target, c.t, c.q,
        None, None, {}, np.arange(2, m + 2), frame=frame, sheet=layout.sheet,
    )  # fmt: skip


def off_table(rng: np.random.Generator, per_plane: int = 40) -> list[tuple[np.ndarray, float]]:
    """Configurations (k, n) of the true robot aiming at points spread on each plane, with its height."""
    out = []
    for z in PLANES:
        qs = []
        for p in np.c_[
            rng.uniform(300, 650, per_plane), rng.uniform(-300, 300, per_plane), np.full(per_plane, z)
        ]:
            try:
                qs.append(aim(TRUTH, p, 1, rng, (0.0, np.radians(35)), (100.0, 900.0))[0])
            except AimingError:
                continue
        out.append((np.array(qs), z))
    return out


def plane_error(model, configs) -> np.ndarray:
    """Distances (k,) mm between the model's and the truth's spots on each plane."""
    e = [
        np.linalg.norm((predict_spots(model, q, z)[0] - predict_spots(TRUTH, q, z)[0])[:, :2], axis=1)
        for q, z in configs
    ]
    return np.concatenate(e)


def flange_error(model, rng, n: int = 200) -> np.ndarray:
    """Distances (n,) mm between the model's and the truth's aperture at random configurations."""
    q = rng.uniform(NOMINAL.limits[:, 0] + 0.1, NOMINAL.limits[:, 1] - 0.1, (n, NOMINAL.n))
    M = np.eye(4)
    M[:3, 3] = model.aperture
    Mt = M.copy()
    Mt[:3, 3] = TRUTH.aperture
    return np.linalg.norm(fk(model.screws, M, q)[:, :3, 3] - fk(TRUTH.screws, Mt, q)[:, :3, 3], axis=1)


def main(seeds: int = 8) -> None:
    configs = off_table(np.random.default_rng(99))
    for name, base, per in (("thesis P1-P3", THESIS, 15), ("3 x 3 grid", GRID, 5)):
        sheet = as_sheet(base)
        errs, poses = {"sheet": [], "base": []}, []
        for seed in range(seeds):
            rng = np.random.default_rng([seed, 23])
            pose = SheetPose(*rng.uniform(-30, 30, 2), rng.uniform(-10, 10))
            true = sheet.in_base(pose)
            c = simulate_captures(TRUTH, true, per, NOISE, rng)
            fit_sheet = identify_lm(session(sheet, c, "sheet")).model
            fit_base = identify_lm(session(true, c, "base")).model
            es, eb = plane_error(fit_sheet, configs), plane_error(fit_base, configs)
            errs["sheet"].append(es)
            errs["base"].append(eb)
            d = fit_sheet.sheet
            poses.append((np.hypot(d.x_mm - pose.x_mm, d.y_mm - pose.y_mm), abs(d.yaw_deg - pose.yaw_deg)))
            print(
                f"{name} seed {seed}: sheet at ({pose.x_mm:+.1f}, {pose.y_mm:+.1f}) mm "
                f"{pose.yaw_deg:+.2f} deg, found within {poses[-1][0]:.3f} mm and {poses[-1][1]:.4f} deg; "
                "plane spots RMS: sheet fit "
                f"{np.sqrt(np.mean(es**2)):.3f} mm, base-frame points {np.sqrt(np.mean(eb**2)):.3f} mm",
                flush=True,
            )
        s, b = (np.sqrt(np.mean(np.concatenate(errs[k]) ** 2)) for k in ("sheet", "base"))
        p = np.array(poses)
        print(
            f"{name}, {seeds} seeds, {sum(len(q) for q, _ in configs)} off-table configurations on planes "
            f"{PLANES} mm: pooled RMS sheet fit {s:.3f} mm / true base-frame points {b:.3f} mm = "
            f"{s / b:.3f}; sheet pose error max {p[:, 0].max():.3f} mm, {p[:, 1].max():.4f} deg (median "
            f"{np.median(p[:, 0]):.3f} mm, {np.median(p[:, 1]):.4f} deg)\n"
        )
    issue_case(configs)


def issue_case(configs) -> None:
    """Issue 23's example: the sheet 5 mm / -3 mm / 1.5 deg away from where the thesis layout says."""
    rng = np.random.default_rng(5)
    sheet = as_sheet(THESIS)
    pose = SheetPose(5.0, -3.0, 1.5)
    c = simulate_captures(TRUTH, sheet.in_base(pose), 15, NOISE, rng)
    before = identify_lm(session(THESIS, c, "base")).model  # the layout's points taken as base-frame points
    after = identify_lm(session(sheet, c, "sheet")).model
    frng = np.random.default_rng(1)
    p4 = np.array([441.0, 160.0])
    for label, m in (
        ("nominal", NOMINAL),
        ("before (points as the layout says)", before),
        ("after (sheet)", after),
    ):
        j1 = np.linalg.norm(
            np.cross(m.screws[0, :3], m.screws[0, 3:])[:2]
            - np.cross(TRUTH.screws[0, :3], TRUTH.screws[0, 3:])[:2]
        )
        fl = flange_error(m, frng)
        pe = plane_error(m, configs)
        print(
            f"5 mm / -3 mm / 1.5 deg, {label}: joint 1's axis {j1:.2f} mm from the truth's; aperture "
            f"positions {fl.mean():.2f} mm mean, {fl.max():.2f} max; off-table plane spots RMS "
            f"{np.sqrt(np.mean(pe**2)):.2f} mm"
            + (f"; sheet found at {m.sheet.as_dict()}" if m.sheet is not None else "")
        )
    print(f"(P4 at {p4.tolist()} on the sheet, the thesis's validation point)")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
