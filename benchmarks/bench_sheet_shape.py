"""Issue 52 item 2: is a curled, sheared sheet named, and does modelling it help validate? (mm)

Usage: python benchmarks/bench_sheet_shape.py [CURLED_SEEDS [FLAT_SESSIONS [WORKERS [BULGE_LO,BULGE_HI]]]]
(default 6 20 2 1.4,1.9); python benchmarks/bench_sheet_shape.py --null N: the F test's own false-naming
rate on N of the solver's simulated camera sessions of a flat, square sheet (`lasercal simulate
panda_thesis_identified --measured 1 --spot-sigma 0.03 --per-point 9 --sheet-pose 452 3 1.0`, no
photos: Gaussian spots, the world the test assumes).

Each seed S draws one fake world (`capture --backend fake --auto --per-point 9 --aim-noise 3 --camera fake
--seed S`, the sheet at `--place 450 0 0`) twice:

* curled: every effect on, the paper's bulge drawn within BULGE mm (the fake world's own range is 0.1-0.3
  mm; the issue's MuJoCo paper curls 1.4-1.9 mm: fakeworld.PAPER_BULGE_MM is set in this process), the
  printer's shear as the world draws it (up to 1.5 mm per m);
* flat: the same world without paper-curl and print-shear (a flat, square print).

Each session is solved with `solve --extend auto` (the sheet's shape tested: `--sheet-shape auto`), the
curled ones also with `--sheet-shape flat`, and validated at P6 (`validate --backend fake -n 30 --point P6`,
validate's `error mean`). Flat sessions beyond the curled seeds are solved only (the false-naming count).
Prints one row per session and the table: named (of N curled), named falsely (of M flat), P6 error with and
without the shape against flat paper in the same world.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import sys
import tempfile
from multiprocessing import Pool
from pathlib import Path

ALL = "repeatability,distortion,occlusion,ellipse,subsurface,print-scale,sheet-height,table-slope"
CURLED = ALL + ",paper-curl,print-shear"


def _main(args, cwd) -> str:
    """``lasercal ARGS`` in this process (in folder ``cwd``), its standard output."""
    import os

    from lasercal.collector.cli.main import main

    out, here = io.StringIO(), os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            rc = main(list(args))
    finally:
        os.chdir(here)
    if rc != 0:
        raise RuntimeError(f"lasercal {' '.join(args)}: exit {rc}")
    return out.getvalue()


def _validate(model: str, where: Path) -> float:
    text = _main(
        [
            "validate",
            model,
            "--layout",
            "sheet/layout.yaml",
            "--backend",
            "fake",
            "-n",
            "30",
            "--point",
            "P6",
            "-o",
            f"val_{Path(model).stem}",
        ],
        where,
    )
    return float(re.findall(r"error mean ([0-9.]+) mm", text)[-1])


def session(task) -> dict:
    """One session: kind 'curled' or 'flat', its seed, whether to validate, the bulge range."""
    kind, seed, validate, bulge = task
    from lasercal.collector.hardware import fakeworld

    fakeworld.PAPER_BULGE_MM = bulge
    with tempfile.TemporaryDirectory() as d:
        where = Path(d)
        _main(["sheet", "-o", "sheet", "--place", "450", "0", "0"], where)
        _main(
            [
                "capture",
                "--layout",
                "sheet/layout.yaml",
                "--robot",
                "panda",
                "--backend",
                "fake",
                "--auto",
                "--per-point",
                "9",
                "--aim-noise",
                "3",
                "--camera",
                "fake",
                "--seed",
                str(seed),
                "--photos",
                "none",
                "--effects",
                CURLED if kind == "curled" else ALL,
                "-o",
                "s",
            ],
            where,
        )
        rep = json.loads(_main(["solve", "s", "-o", "m.yaml", "--extend", "auto", "--json"], where))
        sh = rep.get("sheet_shape", {})
        row = {
            "kind": kind,
            "seed": seed,
            "kept": bool(sh.get("kept")),
            "p": sh.get("p_value"),
            "gain": (sh.get("holdout") or {}).get("gain_percent"),
            "curl_mm": sh.get("curl_mm"),
            "shear": sh.get("shear_mm_per_m"),
            "effect": rep.get("diagnosis", {}).get("effect"),
        }
        if kind == "curled":
            import yaml

            world = yaml.safe_load((where / "s" / "session.yaml").read_text())["simulated"]["world"]
            row["true_bulge_mm"], row["true_shear"] = world["paper_bulge_mm"], 1000 * world["print_shear"]
        if validate:
            row["p6_mm"] = _validate("m.yaml", where)
            if kind == "curled":
                _main(["solve", "s", "-o", "flat.yaml", "--extend", "auto", "--sheet-shape", "flat"], where)
                row["p6_flat_model_mm"] = _validate("flat.yaml", where)
    print(json.dumps(row), flush=True)
    return row


def null(n: int) -> None:
    """The false-naming rate on the solver's own simulated flat-sheet camera sessions (module docstring)."""
    named = 0
    with tempfile.TemporaryDirectory() as d:
        where = Path(d)
        _main(["sheet", "-o", "sheet", "--place", "450", "0", "0"], where)
        for seed in range(n):
            sim = ["simulate", "panda_thesis_identified", "--layout", "sheet/layout.yaml", "--per-point", "9"]
            sim += ["--measured", "1", "--spot-sigma", "0.03", "--aim-noise", "3", "--sheet-pose", "452", "3"]
            _main([*sim, "1.0", "--seed", str(seed), "-o", f"n{seed}", "--force"], where)
            sh = json.loads(_main(["solve", f"n{seed}", "-o", f"n{seed}.yaml", "--json"], where))[
                "sheet_shape"
            ]
            named += sh["kept"]
            print(
                f"seed {seed}: kept {sh['kept']}, p = {sh['p_value']:.3g}, curl {sh['curl_mm']:.3f} mm",
                flush=True,
            )
    print(f"simulated flat sheets: the shape named falsely in {named} of {n}")


def main(argv: list[str]) -> None:
    if argv[:1] == ["--null"]:
        null(int(argv[1]) if len(argv) > 1 else 20)
        return
    n_curled = int(argv[0]) if argv else 6
    n_flat = int(argv[1]) if len(argv) > 1 else 20
    workers = int(argv[2]) if len(argv) > 2 else 2
    bulge = tuple(float(v) for v in argv[3].split(",")) if len(argv) > 3 else (1.4, 1.9)
    tasks = []  # a seed's curled and flat sessions side by side: the table's pairs come first
    for s in range(max(n_curled, n_flat)):
        tasks += [("curled", s, True, bulge)] * (s < n_curled)
        tasks += [("flat", s, s < n_curled, bulge)] * (s < n_flat)
    with Pool(workers) as pool:
        rows = pool.map(session, tasks, chunksize=1)
    curled = [r for r in rows if r["kind"] == "curled"]
    flat = {r["seed"]: r for r in rows if r["kind"] == "flat"}
    print(f"\npaper bulge {bulge[0]}-{bulge[1]} mm; every other effect on (flat: no curl, no shear)")
    print(
        f"{'seed':>4} {'bulge mm':>8} {'shear mm/m':>10} {'named':>6} {'curl mm':>8} {'p':>9} {'gain %':>7} "
        f"{'P6 shape':>9} {'P6 flat model':>13} {'P6 flat paper':>13} {'flat paper named':>16}"
    )
    for r in curled:
        f = flat.get(r["seed"], {})
        print(
            f"{r['seed']:4d} {r['true_bulge_mm']:8.2f} {r['true_shear']:10.2f} "
            f"{'yes' if r['kept'] else 'no':>6} "
            f"{r['curl_mm'] or 0:8.2f} {r['p'] or float('nan'):9.2g} {r['gain'] or float('nan'):7.1f} "
            f"{r['p6_mm']:9.3f} {r['p6_flat_model_mm']:13.3f} {f.get('p6_mm', float('nan')):13.3f} "
            f"{'yes' if f.get('kept') else 'no':>16}"
        )
    named = sum(r["kept"] for r in curled)
    false = sum(r["kept"] for r in flat.values())
    print(
        f"curled: the sheet named in {named} of {len(curled)}; "
        f"flat paper: named falsely in {false} of {len(flat)}"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
