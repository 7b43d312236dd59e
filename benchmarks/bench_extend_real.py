"""What ``--extend auto`` names on the real data, and its outer-fold gain next to the one reported before
(issue 52, item 4: the UR10 series, the four MUKCa Pandas, Agile Justin).

Run: python benchmarks/bench_extend_real.py [DATA] [--only mukca,justin,ur10] [--no-nested]
(DATA: ../shared/data by default; prints a table, no assertions; 11-15 min wall, ~480 s CPU, 2 cores)

Every session is prepared and solved by the public commands, as docs/real-data.md and docs/position.md
prepare them, in a temporary folder (the data are read from DATA, never copied into the repository):

* MUKCa: ``lasercal import-mukca DATA/mukca/panda_K -o S``, then ``lasercal solve S -o M.yaml --extend auto
  --payload 0.83,88,0,866 --json`` (the hand and ball of the study; its folds leave one tool position out),
  for panda_1 .. panda_4 and the authors' clean subsets panda_2_clean and panda_4_clean;
* Agile Justin: ``lasercal import-justin DATA/justin/measurements.csv -o S``, then ``lasercal solve S -o
  M.yaml --extend auto --json`` (5 folds by record). Two rows: the diagnosis's finding, whose held-out
  figure has the selection made inside each outer fold, and the joint error map stacked on it, whose keep
  decision is made on the same folds it is scored on (``joint_map.gain_is``);
* UR10: ``lasercal import-ipa DATA/ur10-tracker/Series_X -o X`` for A, B, C, then ``lasercal solve A B C -o
  M.yaml --extend auto`` (pose sessions: ``solver/analysis/pose_cv.py``, no ``--json``; it compares its three
  candidates by leave one series out, makes the choice again inside each outer fold from its two training
  series, and reports those folds' held-out figure and how many chose its best). The ``nested`` row
  (skipped with ``--no-nested``) is an outside check of that: ``extend_auto`` run on the two training series
  of each outer fold, its choice scored on the held-out series.

Columns: the data set; captures (poses for the UR10); what is named (effect and joints, or none and why);
the outer folds that chose the same cause (of those fitted, and how many the agreement rule needs); the
held-out error of the geometry and of what is kept, and the gain; the figure reported before, with the
doc line it is on; the command's wall and CPU time. Held-out metrics are each path's own: the diagnosis's
pooled RMS of the 3-D point error (mm; MUKCa, Justin), the pose protocol's mean position error (mm; UR10).
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
PAYLOAD = "0.83,88,0,866"  # the Franka hand and ball, as the MUKCa study (collector/studies/options.py)
# the four robots, then the authors' subsets with their corrupted tool positions removed (PROVENANCE.md)
PANDAS = ("panda_1", "panda_2", "panda_3", "panda_4", "panda_2_clean", "panda_4_clean")
# data set -> (doc:line, geometric -> extended held out, its metric, what was named there)
REPORTED = {
    "panda_1": ("docs/real-data.md:46,115", 0.858, 0.711, "spread RMS", "eccentricity j2,3"),
    "panda_2": ("docs/real-data.md:48,116", 0.414, 0.390, "spread RMS", "compliance j3,4,5,6"),
    "panda_3": ("docs/real-data.md:50,118", 0.213, 0.172, "spread RMS", "compliance j2,3,4"),
    "panda_4": ("docs/real-data.md:52,119", 0.259, 0.238, "spread RMS", "compliance j2,3,4"),
    "panda_2_clean": ("docs/real-data.md:116-117", None, None, "", "compliance j3,4"),
    "justin": ("docs/position.md:221,224", 10.22, 3.60, "mean 3-D", "compliance, lateral, ecc."),
    "justin + joint map": ("docs/position.md:221,226", 10.22, 3.51, "mean 3-D", "the same + map"),
    "ur10 A+B+C": ("docs/real-data.md:274", 0.490, 0.236, "mean pos.", "compliance + map"),
    "ur10 nested": ("docs/real-data.md:274", 0.490, 0.233, "mean pos.", "map step/prior nested"),
}


def lasercal(args: list, cwd: Path) -> tuple[str, float, float]:
    """Run the ``lasercal`` command of this interpreter's environment.

    Parameters
    ----------
    args : list of str, the command's arguments
    cwd : Path, where it runs

    Returns
    -------
    stdout, wall seconds, CPU seconds (user + system of the command)
    """
    exe = Path(sys.executable).with_name("lasercal")
    cmd = [str(exe) if exe.exists() else shutil.which("lasercal") or "lasercal", *args]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=True).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return out, time.perf_counter() - t0, cpu


def short(label: str) -> str:
    """A finding's label without its long words: 'joint_compliance at joints 2,3' -> 'compliance j2,3',
    a tree's 'joint_compliance at joints torso_2' -> 'compliance torso_2'."""
    for word, abbreviation in (
        ("joint_compliance", "compliance"),
        ("lateral_compliance", "lateral"),
        ("encoder_eccentricity", "eccentricity"),
        ("joint_map", "map"),
    ):
        label = label.replace(word, abbreviation)
    return re.sub(r" at joints? ", " ", re.sub(r" at joints? (?=\d)", " j", label))


def brief(label: str, width: int = 44) -> str:
    """A label that fits ``width`` characters: each part's effect and its number of joints when too long
    ('compliance (5) + eccentricity (3) + lateral (10)')."""
    label = short(label)
    if len(label) <= width:
        return label
    parts = [p.split(" ", 1) for p in label.split(" + ")]
    return " + ".join(f"{p[0]} ({len(p[1].split(','))})" if len(p) > 1 else p[0] for p in parts)


def diagnosis_row(name: str, solved: dict, wall: float, cpu: float) -> dict:
    """The table's row of a point or position session's ``solve --extend auto --json``.

    Parameters
    ----------
    name : str, the data set
    solved : dict, the command's JSON (its ``diagnosis`` record)
    wall, cpu : float, the command's seconds

    Returns
    -------
    dict: name, captures, named, folds, geometric, extended (held-out RMS of the selection's outer folds,
    mm), refit (the whole session's choice refitted in each of the same folds, as the gain was scored
    before issue 52), fold_mean (the mean over the outer folds of each model's RMS: the MUKCa study's way
    of averaging), choices (each fold's label), rejected (why nothing is named, or None), wall, cpu
    """
    d = solved["diagnosis"]
    acc = d["acceptance"]
    # the selection's own outer folds and finding, before any joint map is stacked on it
    held = acc["holdout_rms_mm"]
    kept = acc["accepted"] and d["effect"] not in ("none", "joint_map")
    parts = [p for p in d["label"].split(" + ") if not p.startswith("joint_map")]
    named = " + ".join(parts) if kept else "none"
    jm = acc.get("joint_map")
    # the whole session's finding refitted from the nominal in each fold: the map stage's base when a map
    # is kept, else solve's own cross-validation of the kept model
    refit = (
        jm["holdout_rms_mm"]["without"]
        if jm and jm["accepted"]
        else solved["cross_validation"]["holdout_rms_mm"]
    )
    fitted = [c for c in acc.get("fold_choices", []) if c["label"] != "failed"]
    return {
        "name": name,
        "captures": solved["captures"],
        "named": named,
        "folds": f"{acc.get('folds_agree', '-')} of {len(fitted)} ({acc.get('folds_needed', '-')} needed, "
        f"{acc.get('folds_same_cause', '-')} exact)",
        "geometric": held["geometric"],
        "extended": held["extended"] if kept else held["geometric"],
        "proposed": held["extended"],
        "refit": refit,
        "fold_mean": (np.mean(acc["fold_rms_mm"]["geometric"]), np.mean(acc["fold_rms_mm"]["extended"])),
        "choices": [short(c["label"]) for c in acc.get("fold_choices", [])],
        "rejected": acc.get("rejected"),
        "wall": wall,
        "cpu": cpu,
    }


def map_row(base: dict, solved: dict) -> dict | None:
    """The joint error map's row on top of a position session's finding, or None when it was not kept.

    Parameters
    ----------
    base : dict, :func:`diagnosis_row`'s row of the same command
    solved : dict, the command's JSON

    Returns
    -------
    dict as :func:`diagnosis_row`'s, held out with the map (its keep decision made on these folds)
    """
    jm = solved["diagnosis"]["acceptance"].get("joint_map")
    if jm is None or not jm["accepted"]:
        return None
    gains = np.round(jm["gain_percent_folds"], 1).tolist()
    without, with_map = jm["holdout_rms_mm"]["without"], jm["holdout_rms_mm"]["with"]
    return base | {
        "name": f"{base['name']} + joint map",
        "named": f"{base['named']} + joint_map",
        "folds": "chosen on them",
        "extended": solved["diagnosis"]["holdout_rms_mm"]["extended"],
        "refit": solved["cross_validation"]["holdout_rms_mm"],
        "choices": [
            f"the map ({jm['knots']} knots) {without:.3f} -> {with_map:.3f} mm over the finding refitted in "
            f"each fold, fold gains {gains} %, {jm['gain_is']}"
        ],
        "wall": None,  # the same command as the finding's row
        "cpu": None,
    }


def solve_diagnosed(name: str, session: Path, extra: list, tmp: Path) -> list:
    """``lasercal solve SESSION --extend auto --json`` and its rows (the map's too, when kept)."""
    out, wall, cpu = lasercal(
        ["solve", str(session), "-o", f"{name}.yaml", "--extend", "auto", "--json", *extra], tmp
    )
    solved = json.loads(out)
    row = diagnosis_row(name, solved, wall, cpu)
    print(f"{name}: {short(row['named'])}, {wall:.0f} s wall, {cpu:.0f} s CPU", flush=True)
    return [r for r in (row, map_row(row, solved)) if r is not None]


def ur10_cli(sessions: list, tmp: Path) -> dict:
    """``lasercal solve A B C -o M.yaml --extend auto``: its held-out table, each outer fold's own choice and
    what it keeps.

    Returns
    -------
    dict as :func:`diagnosis_row`'s (held out: mean position error, mm, leave one series out; 'extended' the
    outer folds' own choices, 'refit' the kept candidate's row of the table)
    """
    out, wall, cpu = lasercal(["solve", *map(str, sessions), "-o", "ur10.yaml", "--extend", "auto"], tmp)
    rows, kept, poses, folds, nested, agree = {}, "?", 0, [], float("nan"), "?"
    for line in out.splitlines():
        if line.startswith("pose sessions: "):  # 'pose sessions: A (11911), B (1495), C (2773); 61.2 s'
            poses = sum(int(part.split("(")[1].rstrip(")")) for part in line.split(";")[0].split(", "))
        elif line.startswith("kept: "):
            kept = line[len("kept: ") :]
        elif line.startswith("  ") and " mm, " in line and "(fitted" in line:
            label, figures = line.strip().rsplit(": ", 1)
            rows[label] = float(figures.split(" mm")[0])
        elif line.startswith("  ") and " held out: " in line:  # '  A held out: LABEL, 0.174 mm, 0.433 mrad'
            folds.append(line.strip())
        elif line.startswith("held out with each fold's own choice: "):  # '...: 0.236 mm, ...; 3 of 3 folds'
            nested = float(line.split(": ")[1].split(" mm")[0])
            agree = line.split("; ")[-1].split(" folds chose")[0] + " (" + line.rsplit("(", 1)[1]
    print(f"ur10 A+B+C: kept {kept}, {wall:.0f} s wall, {cpu:.0f} s CPU", flush=True)
    return {
        "name": "ur10 A+B+C",
        "captures": poses,
        "named": kept,
        "folds": agree,
        "geometric": rows["geometric"],
        "extended": nested,
        "refit": rows[kept],
        "choices": [f"{short(k)}: {v:.3f} mm" for k, v in rows.items()] + folds,
        "rejected": None,
        "wall": wall,
        "cpu": cpu,
    }


def ur10_nested(sessions: list) -> dict:
    """``--extend auto``'s choice made inside each outer fold (leave one series out): ``extend_auto`` on the
    two training series alone, its choice scored on the held-out series as the pose protocol scores it.

    Parameters
    ----------
    sessions : list of Path, the A, B and C pose sessions

    Returns
    -------
    dict as :func:`diagnosis_row`'s (held out: mean position error, mm; geometric: the geometry fitted on
    the same training series)
    """
    from lasercal.solver.analysis.pose_cv import extend_auto, half_scores
    from lasercal.solver.formats.poses import load_pose_session
    from lasercal.solver.identify.poses import fit_poses

    S = [load_pose_session(s) for s in sessions]
    nominal = S[0].robot
    t0, c0 = time.perf_counter(), time.process_time()
    geo, ext, choices = [], [], []
    for k, held in enumerate(S):
        train = [s for j, s in enumerate(S) if j != k]
        auto = extend_auto(train, nominal)
        geo.append(half_scores(fit_poses(train, nominal).model, held)[0].mean())
        ext.append(half_scores(auto.fit.model, held)[0].mean())
        choices.append(auto.chosen)
        print(
            f"  nested, {held.name} held out: chose {auto.chosen}: {geo[-1]:.3f} -> {ext[-1]:.3f} mm",
            flush=True,
        )
    same = max(choices.count(c) for c in choices)
    return {
        "name": "ur10 nested",
        "captures": sum(s.m for s in S),
        "named": max(set(choices), key=choices.count),
        "folds": f"{same} of {len(S)}",
        "geometric": float(np.mean(geo)),
        "extended": float(np.mean(ext)),
        "refit": None,
        "choices": choices,
        "rejected": None,
        "wall": time.perf_counter() - t0,
        "cpu": time.process_time() - c0,
    }


def gain(geo: float, ext: float) -> float:
    """The held-out gain (%) of ``ext`` over ``geo``."""
    return 100.0 * (geo - ext) / geo


def print_table(rows: list) -> None:
    """The table as markdown (module docstring), then each row's full finding, its folds' choices and why
    nothing was named."""
    cols = (
        "data set",
        "captures",
        "`--extend auto` names",
        "folds agreeing",
        "held out: geometric -> extended (gain)",
        "refitted per fold",
        "reported before (gain, metric; named)",
        "doc:line",
        "wall / CPU s",
    )
    print("\n| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        doc, g0, e0, metric, what = REPORTED.get(r["name"], ("-", None, None, "", "-"))
        refit = "-" if r["refit"] is None else f"{r['refit']:.3f} ({gain(r['geometric'], r['refit']):+.1f} %)"
        now = f"{r['geometric']:.3f} -> {r['extended']:.3f} ({gain(r['geometric'], r['extended']):+.1f} %)"
        before = what if g0 is None else f"{g0:.3f} -> {e0:.3f} ({gain(g0, e0):+.1f} %, {metric}; {what})"
        cells = (r["name"], r["captures"], brief(r["named"]), r["folds"], now, refit, before, doc)
        timing = "(the row above)" if r["wall"] is None else f"{r['wall']:.0f} / {r['cpu']:.0f}"
        print("| " + " | ".join(map(str, (*cells, timing))) + " |")
    print()
    for r in rows:
        print(f"{r['name']}: names {short(r['named'])}; folds: " + "; ".join(map(short, r["choices"])))
        if r["name"] in PANDAS:  # the study's average, to set beside docs/real-data.md's table
            g, e = r["fold_mean"]
            print(f"  mean of the outer folds' RMS: {g:.3f} -> {e:.3f} mm ({gain(g, e):+.1f} %)")
        if r.get("rejected"):
            print(f"  not named: {r['rejected']} (held out with it: {r['proposed']:.3f} mm)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data", nargs="?", default=str(DATA))
    ap.add_argument("--only", default="mukca,justin,ur10", help="comma-separated: mukca, justin, ur10")
    ap.add_argument("--no-nested", action="store_true", help="skip the UR10's selection inside the folds")
    a = ap.parse_args()
    data, only = Path(a.data), a.only.split(",")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_extend_real_") as t:
        tmp = Path(t)
        if "mukca" in only:
            for robot in PANDAS:
                lasercal(["import-mukca", str(data / "mukca" / robot), "-o", robot], tmp)
                rows += solve_diagnosed(robot, tmp / robot, ["--payload", PAYLOAD], tmp)
        if "justin" in only:
            lasercal(["import-justin", str(data / "justin" / "measurements.csv"), "-o", "justin"], tmp)
            rows += solve_diagnosed("justin", tmp / "justin", [], tmp)
        if "ur10" in only:
            series = [tmp / s for s in "ABC"]
            for s in series:
                lasercal(["import-ipa", str(data / "ur10-tracker" / f"Series_{s.name}"), "-o", s.name], tmp)
            rows.append(ur10_cli(series, tmp))
            if not a.no_nested:
                rows.append(ur10_nested(series))
    print_table(rows)


if __name__ == "__main__":
    main()
