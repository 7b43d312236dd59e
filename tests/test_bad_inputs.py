"""Bad input, every command: exit 2, one line naming the file or option, no traceback, nothing written.

Each case runs ``main([...])`` in-process on copies of small valid inputs (a simulated
session, its identified model, a validation run, circle-point measurements, a MUKCa robot
folder and its point session) with one thing wrong, and checks: exit code 2; stderr is exactly
one line ``lasercal: error: ...`` (argparse's own: ``lasercal COMMAND: error: ...``) that names the
file or option at fault; no traceback; the output path was not created; no file in the working folder
changed (bytes and mtime). A watchdog turns a hang into a failure.

Cases are grouped by category (the first word of each test id): ``traceback`` (files a newcomer
saves wrongly: not UTF-8, UTF-16 without a byte-order mark, binary, empty, a folder for a file),
``silent`` (values that used to pass: metres for mm, degrees for rad, units), ``culprit`` (a bad
value named with its option or file, line and column), ``output`` (an output path that would
damage or lose something), ``degenerate`` (input that makes the problem unidentifiable, named
as such before the fit) and ``warning`` (plausible but suspicious input: one warning line naming
it, exit 0, the output written). The option and output cases are also generated from the
declarations of every command (:mod:`collector.cli.options`), so a new option or output is
covered when it is declared. ``python tests/test_bad_inputs.py`` prints the count per command
and category.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import COMMANDS, build_parser, main
from lasercal.solver.whole import WHOLE, dump_yaml

MUKCA = Path(__file__).resolve().parents[2] / "shared" / "data" / "mukca"
URDF = Path(__file__).resolve().parent / "data" / "ur5.urdf"
WATCHDOG_S = 30


GOALS = "x,y,z\n400,0,500\n450,20,480\n"  # goals of lasercal correct, mm
JUSTIN_RECORDS = [  # DLR's Justin file: 19 joint values (rad), 2 x 3 marker positions (m) a record
    (k, "[" + " ".join(["0.1"] * 19) + "]", f'"[[-1.8  2.2  1.{k}]\n [-3.0  1.6  1.8]]"') for k in range(3)
]


def justin_text(records) -> str:
    return ",joints,markers\n" + "".join(f"{k},{q},{mk}\n" for k, q, mk in records)


JUSTIN = justin_text(JUSTIN_RECORDS)
PRIOR = "format: lasercal-prior/1\nunits: {length: mm, angle: rad}\nprior: {offset_mm: 4.0}\n"


def ipa_text(m: int = 30) -> str:
    """A series file as ipa-robot-accuracy publishes it (';', decimal commas, Euler XYZ in degrees) of the
    nominal UR10 seen by a tracker 3 m away, the probe 93 mm off the flange."""
    from scipy.spatial.transform import Rotation

    from lasercal.solver.formats.ipa import POSE, UR_JOINTS
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.kinematics.poe import exp6, fk

    ur = load_model("ur10")
    q = np.random.default_rng(5).uniform(-2.5, 2.5, (m, 6))
    T = (
        exp6(np.r_[0.1, -0.2, 0.5, 2500.0, -1500.0, -1200.0])
        @ fk(ur.screws, ur.ee_pose, q)
        @ exp6(np.r_[0, 0, -1.5708, 0, 0.3, 93.0])
    )
    eul = Rotation.from_matrix(T[:, :3, :3]).as_euler("XYZ", degrees=True)
    head = ["Timestamp", *UR_JOINTS, "measurement_temperature"] + [f"measurement_{k}" for k in POSE]
    rows = [[2.02011e13, *q[i], 21.7, *T[i, :3, 3], *eul[i]] for i in range(m)]
    text = [";".join(head)] + [";".join(f"{v:.9g}".replace(".", ",") for v in r) for r in rows]
    return "\n".join(text) + "\n"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Valid inputs, made once: sess/, model.yaml, layout.yaml, configs.csv, val/, fp.csv, mukca/, pos/
    (a position session of the UR5 URDF, which it names as 'robot: arm.urdf' beside its captures),
    goals.csv, prior.yaml, sheet/ (a printed sheet and its layout, frame: sheet), shs/ (a session on
    that sheet, displaced from its placement) and shm.yaml (its model, the sheet found)."""
    d = tmp_path_factory.mktemp("valid")
    layout = yaml.safe_load((Path(__file__).resolve().parents[1] / "data/layouts/thesis.yaml").read_text())
    (d / "layout.yaml").write_text(dump_yaml(layout))  # as lasercal writes it: a whole file
    assert main(["simulate", "panda_thesis_identified", "--layout", str(d / "layout.yaml"), "--per-point",
                 "12", "-o", str(d / "sess")]) == 0  # fmt: skip
    assert main(["solve", str(d / "sess"), "-o", str(d / "model.yaml"), "--folds", "0"]) == 0
    assert main(["validate", str(d / "model.yaml"), "--backend", "fake", "-n", "2", "-o", str(d / "val"),
                 "--layout", str(d / "layout.yaml")]) == 0  # fmt: skip
    assert main(["simulate-fullpose", "--robot", "panda", "--configs", "6", "--angles", "4",
                 "-o", str(d / "fp.csv")]) == 0  # fmt: skip
    q = np.loadtxt(d / "sess" / "captures.csv", delimiter=",", skiprows=1, usecols=range(2, 9))[:3]
    (d / "configs.csv").write_text(
        "q1,q2,q3,q4,q5,q6,q7\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in q)
    )
    assert main(["simulate", str(URDF), "--measurement", "position", "--configs", "8", "--noise", "0.01",
                 "-o", str(d / "pos")]) == 0  # fmt: skip
    shutil.copy(URDF, d / "pos" / "arm.urdf")
    _edit_yaml(d / "pos" / "session.yaml", _set("robot", "arm.urdf"))
    if (MUKCA / "panda_1" / "front").is_dir():
        shutil.copytree(MUKCA / "panda_1" / "front", d / "mukca" / "panda_1" / "front")
        assert main(["import-mukca", str(d / "mukca" / "panda_1"), "-o", str(d / "pt")]) == 0
    T = np.tile(np.eye(4), (4, 1, 1))  # measured full poses (q, R, origin mm) of the nominal Panda
    rcols = [f"r{i}{j}" for i in range(1, 4) for j in range(1, 4)]
    rows = [",".join(repr(float(v)) for v in [*q[i % 3] * 0.9, *T[i, :3, :3].ravel(), 300.0 + i, 20.0, 500.0])
            for i in range(4)]  # fmt: skip
    (d / "poses.csv").write_text(",".join(Q + rcols + ["x", "y", "z"]) + "\n" + "\n".join(rows) + "\n")
    (d / "goals.csv").write_text(GOALS)
    (d / "prior.yaml").write_text(PRIOR)
    (d / "justin.csv").write_text(JUSTIN)
    (d / "ipa").mkdir()
    (d / "ipa" / "measurements_test.csv").write_text(ipa_text())
    assert main(["import-ipa", str(d / "ipa"), "-o", str(d / "ps")]) == 0
    assert main(["solve", str(d / "ps"), "-o", str(d / "pmodel.yaml"), "--folds", "0"]) == 0
    (d / "pcfg.csv").write_text("q1,q2,q3,q4,q5,q6\n0.1,-1.2,1.1,-0.5,0.7,0.2\n0.3,-1.0,0.9,-0.4,0.6,0.1\n")
    assert main(["sheet", "-o", str(d / "sheet"), "--place", "450", "0", "0"]) == 0
    for drawing in ("sheet.pdf", "sheet.svg"):  # read by no command: not copied for every case
        (d / "sheet" / drawing).unlink()
    assert main(["simulate", "panda_thesis_identified", "--layout", str(d / "sheet" / "layout.yaml"),
                 "--per-point", "4", "--sheet-pose", "455", "5", "2", "-o", str(d / "shs")]) == 0  # fmt: skip
    assert main(["solve", str(d / "shs"), "-o", str(d / "shm.yaml"), "--folds", "0"]) == 0
    return d


def _snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (not below a symbolic link): mtime and content hash."""
    return {
        str(p.relative_to(folder)): (p.stat().st_mtime_ns, hashlib.sha1(p.read_bytes()).hexdigest())
        for root, _, names in os.walk(folder)
        for p in sorted(Path(root) / n for n in names)
        if not p.is_symlink()
    }


def _work_copy(base: Path, d: Path) -> Path:
    """A copy of the valid inputs to spoil; the photos (5 MB, never spoiled) are linked, not copied."""
    shutil.copytree(base, d, ignore=lambda folder, names: ["photos"] if folder == str(base / "val") else [])
    (d / "val" / "photos").symlink_to(base / "val" / "photos")
    return d


def _edit_yaml(path: Path, fn) -> None:
    d = yaml.safe_load(path.read_text())
    fn(d)
    path.write_text(yaml.safe_dump(d, sort_keys=False))


def _set(*keys_value):
    """An edit of a YAML mapping: _set('plane', 'z', nan) sets d['plane']['z'] = nan."""
    *keys, value = keys_value

    def fn(d):
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return fn


def _csv_cell(path: Path, row: int, col: str, text: str) -> None:
    """Replace one cell (data row ``row``, 0-based, after the header and comments) of a CSV file."""
    lines = path.read_text().splitlines()
    h = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    header = lines[h].split(",")
    cells = lines[h + 1 + row].split(",")
    cells[header.index(col)] = text
    lines[h + 1 + row] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def _scale_csv(path: Path, cols, factor: float) -> None:
    lines = path.read_text().splitlines()
    h = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    header = lines[h].split(",")
    idx = [header.index(c) for c in cols]
    for i in range(h + 1, len(lines)):
        cells = lines[i].split(",")
        for j in idx:
            cells[j] = repr(float(cells[j]) * factor)
        lines[i] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


def _latin1(rel: str):
    def fn(d: Path):
        p = d / rel
        p.write_bytes(p.read_bytes().replace(b"\n", "\n# caf\xe9 \xff\n".encode("latin-1"), 1))

    return fn


def _yaml(rel: str, *edits):
    def fn(d: Path):
        for e in edits:
            _edit_yaml(d / rel, e)

    return fn


def _cell(rel: str, row: int, col: str, text: str):
    return lambda d: _csv_cell(d / rel, row, col, text)


def _touch(rel: str, text: str = "keep me\n"):
    def fn(d: Path):
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_text(text)

    return fn


def _mkdir(rel: str, with_file: bool = True):
    def fn(d: Path):
        (d / rel).mkdir(parents=True, exist_ok=True)
        if with_file:
            (d / rel / "keep.txt").write_text("keep me\n")

    return fn


def _degrees(rel: str, cols):
    return lambda d: _scale_csv(d / rel, cols, 180 / np.pi)


def _metres(rel: str, cols):
    return lambda d: _scale_csv(d / rel, cols, 1e-3)


def _rm(rel: str):
    return lambda d: (d / rel).unlink()


def _keep_only(rel: str, n: int):
    """Keep the header and the first n data rows of a CSV."""

    def fn(d: Path):
        lines = (d / rel).read_text().splitlines()
        (d / rel).write_text("\n".join(lines[: 1 + n]) + "\n")

    return fn


Q = [f"q{j}" for j in range(1, 8)]
FAKE_CAPTURE = ["capture", "--backend", "fake", "--auto", "--layout", "{d}/layout.yaml", "--per-point", "2"]
VALIDATE = ["validate", "{d}/model.yaml", "--backend", "fake", "-n", "3", "--layout", "{d}/layout.yaml"]
SIMULATE = ["simulate", "panda", "--layout", "{d}/layout.yaml", "--per-point", "3"]
SOLVE = ["solve", "{d}/sess", "--folds", "0"]
SIMFP = ["simulate-fullpose", "--robot", "panda", "--configs", "4", "--angles", "4"]
FULLPOSE = ["fullpose", "{d}/fp.csv", "--robot", "panda"]
REPORT = ["report", "{d}/sess", "{d}/val", "--bootstrap", "0", "--refits", "0"]
DIAGNOSE = ["diagnose", "{d}/sess", "--bootstrap", "0", "--refits", "0"]
EXPORT = ["export", "{d}/model.yaml"]
PREDICT = ["predict", "{d}/model.yaml", "{d}/configs.csv"]
IMPORT = ["import-mukca", "{d}/mukca/panda_1"]
JUSTIN_IMPORT = ["import-justin", "{d}/justin.csv"]
IPA_IMPORT = ["import-ipa", "{d}/ipa"]
REGISTER = ["register", "{d}/pmodel.yaml", "{d}/ps"]
PLAN = ["plan", "{d}/sess", "--next", "2"]
STUDY = ["study-mukca", "{d}/mukca", "--robots", "panda_1", "--quick"]

# (category, id, argv, setup, needle in the message); "{o}" is the output path (must not appear), "{d}" the
# folder
CASES: list[tuple] = []
CATEGORIES = ("traceback", "torn", "silent", "culprit", "output", "degenerate", "warning")


def category(cid: str) -> str:
    """A case's category from its id (the sections below mix them)."""
    c = cid.lower()
    if any(w in c for w in ("utf", "binary", "empty file", "a folder for", "not xml", "bom")):
        return "traceback"
    if any(w in c for w in ("metres", "degrees", "units")):
        return "silent"
    if any(w in c for w in ("same point", "equal", "collinear", "coincident", "copies", "one capture")):
        return "degenerate"
    if " -o " in c or "--report" in c or "--overlay" in c or "-output" in c:
        return "output"
    return "culprit"


def case(cid, argv, setup=None, needle=None, cat=None):
    CASES.append((cat or category(cid), cid, argv, setup, needle))


# --- 1. option values: impossible, non-finite, no bound ------------------------------------------------
OPTION_VALUES = {
    "capture": (FAKE_CAPTURE + ["-o", "{o}"], {
        "--hold": ["-1", "0", "nan", "inf", "abc"],
        "--speed-threshold": ["0", "-0.1", "nan", "inf"],
        "--dynamics": ["0", "-0.1", "0.5", "nan"],
        "--per-point": ["0", "-3", "1.5"],
        "--aim-noise": ["-1", "nan"],
        "--aperture-z": ["nan", "-825", "inf", "0.825"],
        "--auto-pace": ["-1", "nan"],
        "--seed": ["-1"],
        "--ros-port": ["0", "70000"],
        "--until": ["0", "-1", "nan", "inf"],
        "--max-step": ["0", "-0.5", "nan", "4"],
        "--guide": ["fly"],
        "--effects": ["fly", "all,rain", ""],
    }),
    "validate": (VALIDATE + ["-o", "{o}"], {
        "--hold": ["-1", "0", "nan"],
        "--speed-threshold": ["0", "-1", "inf"],
        "--dynamics": ["0", "0.31", "-1", "nan"],
        "-n": ["0", "-5", "nan"],
        "--seed": ["-1"],
        "--max-step": ["0", "-0.5", "nan", "4"],
    }),
    "simulate": (SIMULATE + ["-o", "{o}"], {
        "--per-point": ["0", "-1"],
        "--aim-noise": ["-1", "nan", "inf"],
        "--seed": ["-2"],
    }),
    "solve": (SOLVE + ["-o", "{o}"], {"--folds": ["-1", "1", "nan"], "--payload": ["1,2", "0,0,0,0"]}),
    "report": (REPORT + ["-o", "{o}"], {"--bootstrap": ["-1", "nan"], "--refits": ["-1"], "--seed": ["-1"]}),
    "diagnose": (DIAGNOSE + ["--report", "{o}"], {
        "--alpha": ["0", "1", "-0.1", "nan"],
        "--bootstrap": ["-1"],
        "--refits": ["-1"],
        "--payload": ["1,2", "-1,0,0,0", "nan,0,0,0", "a,b,c,d"],
    }),
    "predict": (PREDICT, {"--plane-z": ["nan", "inf"], "--payload": ["1,2", "0,0,0,0"]}),
    "simulate-fullpose": (SIMFP + ["-o", "{o}"], {
        "--configs": ["0", "-1"],
        "--angles": ["0", "2"],
        "--step": ["0", "nan", "400"],
        "--noise": ["-1", "nan"],
        "--radius": ["0", "-1", "nan"],
        "--offset": ["nan"],
    }),
    "fullpose": (FULLPOSE + ["-o", "{o}"], {"--folds": ["-1", "1"], "--seed": ["-1"]}),
    "study-mukca": (STUDY + ["-o", "{o}"], {"--bootstrap": ["-1", "0"], "--seed": ["-1"]}),
    "demo": (["demo", "-o", "{o}"], {"--seed": ["-1"]}),
    "plan": (PLAN + ["-o", "{o}"], {
        "--next": ["0", "-1", "nan"],
        "--aim-noise": ["0", "-1", "nan"],
        "--seed": ["-1"],
    }),
}  # fmt: skip
for cmd, (argv, opts) in OPTION_VALUES.items():
    for opt, values in opts.items():
        for v in values:
            case(f"{cmd} {opt} {v}", argv + [opt, v], None, opt.lstrip("-").split("-")[0], "culprit")

case("simulate --effect-size nan", SIMULATE + ["-o", "{o}", "--effect", "joint_compliance", "--effect-size",
     "nan"], None, "--effect-size")  # fmt: skip
case("simulate --effect-joints 9", SIMULATE + ["-o", "{o}", "--effect", "joint_compliance", "--effect-size",
     "1e-4", "--effect-joints", "9"], None, "--effect-joints")  # fmt: skip
case("simulate --effect-joints x", SIMULATE + ["-o", "{o}", "--effect", "joint_compliance", "--effect-size",
     "1e-4", "--effect-joints", "x"], None, "--effect-joints")  # fmt: skip
case(
    "simulate --effect no size",
    SIMULATE + ["-o", "{o}", "--effect", "joint_compliance"],
    None,
    "--effect-size",
)
case("import-mukca --positions nosuch", IMPORT + ["-o", "{o}", "--positions", "nosuch"], None, "nosuch")
case("study-mukca --robots empty", STUDY + ["-o", "{o}", "--robots", ","], None, "--robots")
case(
    "study-mukca --robots missing",
    STUDY[:2] + ["--robots", "panda_9", "--quick", "-o", "{o}"],
    None,
    "panda_9",
)

# --- 2. output paths: generated from every command's declarations (section 6) -------------------------

# --- 3. files: malformed, impossible, suspicious, not UTF-8 ------------------------------------------
nan = float("nan")
LAYOUT_BAD = {
    "layout not utf-8": _latin1("layout.yaml"),
    "layout units m": _yaml("layout.yaml", _set("units", {"length": "m"})),
    "layout in metres": _yaml(
        "layout.yaml", lambda d: d.update(points={k: [c / 1000 for c in v] for k, v in d["points"].items()})
    ),
    "layout plane z nan": _yaml("layout.yaml", _set("plane", "z", nan)),
    "layout plane z text": _yaml("layout.yaml", _set("plane", "z", "low")),
    "layout point off the plane": _yaml("layout.yaml", lambda d: d["points"]["P1"].__setitem__(2, 100.0)),
    "layout validation point = calibration point": _yaml(
        "layout.yaml", lambda d: d["points"].__setitem__("P4", list(d["points"]["P1"]))
    ),
    "layout two calibration points equal": _yaml(
        "layout.yaml", lambda d: d["points"].__setitem__("P2", list(d["points"]["P1"]))
    ),
    "layout collinear": _yaml(
        "layout.yaml", lambda d: d["points"].__setitem__("P2", [521.0, 0.0, d["plane"]["z"]])
    ),
    "layout aiming tilt nan": _yaml("layout.yaml", _set("aiming", {"tilt_deg": [nan, 30]})),
    "layout aiming length negative": _yaml("layout.yaml", _set("aiming", {"length": [-300, -100]})),
    "layout aiming text": _yaml("layout.yaml", _set("aiming", {"tilt_deg": "steep"})),
    "layout aiming length in metres": _yaml("layout.yaml", _set("aiming", {"length": [0.15, 0.6]})),
    "layout not a mapping": lambda d: (d / "layout.yaml").write_text("- a\n- b\n"),
}
for cid, setup in LAYOUT_BAD.items():
    case(f"simulate: {cid}", SIMULATE + ["-o", "{o}"], setup, "layout.yaml")
for cid in ("layout not utf-8", "layout units m", "layout in metres", "layout plane z nan"):
    case(f"capture: {cid}", FAKE_CAPTURE + ["-o", "{o}"], LAYOUT_BAD[cid], "layout.yaml")
    case(f"validate: {cid}", VALIDATE + ["-o", "{o}"], LAYOUT_BAD[cid], "layout.yaml")

MODEL_BAD = {
    "model not utf-8": _latin1("model.yaml"),
    "model limits in degrees": _yaml(
        "model.yaml", lambda d: [j.update(limits=[-166.0, 166.0]) for j in d["joints"]]
    ),
    "model aperture in metres": _yaml(
        "model.yaml", lambda d: d["laser"].update(M=[c / 1000 for c in d["laser"]["M"]])
    ),
    "model plane z text": _yaml("model.yaml", _set("plane", {"z": "floor"})),
    "model laser omega text": _yaml("model.yaml", lambda d: d["laser"].update(omega="up")),
    "model laser v inf": _yaml("model.yaml", lambda d: d["laser"].update(v=[0.0, 0.0, float("inf")])),
    "model extension nan": _yaml(
        "model.yaml", _set("extensions", {"joint_compliance": {"joints": [2], "c": [nan]}})
    ),
    "model drift t0 text": _yaml(
        "model.yaml", _set("extensions", {"drift": {"joints": [2], "r": [1e-6], "t0_s": "noon"}})
    ),
    "model link mass negative": _yaml("model.yaml", _set("links", [{"mass": -1.0, "com": [0, 0, 0]}] * 7)),
    "model home outside limits": _yaml("model.yaml", _set("home", [10.0] * 7)),
    "model units m": _yaml("model.yaml", _set("units", {"length": "m", "angle": "rad"})),
}
for cid, setup in MODEL_BAD.items():
    case(f"export: {cid}", EXPORT + ["-o", "{o}"], setup, "model.yaml")
for cid in ("model not utf-8", "model limits in degrees", "model aperture in metres", "model extension nan"):
    case(f"export --format franka: {cid}", EXPORT + ["--format", "franka", "-o", "{o}"], MODEL_BAD[cid],
         "model.yaml")  # fmt: skip
# --format franka writes franka_description's kinematics.yaml: a Franka arm only, a robot id it knows
case("export --format franka of a robot that is no Franka arm", ["export", "puma560", "--format", "franka",
     "-o", "{o}"], None, "--format franka")  # fmt: skip
case("export --format franka of a URDF that is no Franka arm", ["export", str(URDF), "--format", "franka",
     "-o", "{o}"], None, "--format franka")  # fmt: skip
case("export --format franka of a tree", ["export", "justin", "--format", "franka", "-o", "{o}"], None,
     "--format franka")  # fmt: skip
case("export --robot-id nosuch", EXPORT + ["--format", "franka", "--robot-id", "nosuch", "-o", "{o}"], None,
     "--robot-id")  # fmt: skip
for cid in (
    "model not utf-8",
    "model limits in degrees",
    "model aperture in metres",
    "model extension nan",
):
    case(f"predict: {cid}", PREDICT, MODEL_BAD[cid], "model.yaml")
    case(f"validate: {cid}", VALIDATE + ["-o", "{o}"], MODEL_BAD[cid], "model.yaml")


def _spots(cells: str, row: int = 0):
    """A camera session's spot columns added to captures.csv, ``cells`` (camera_x..camera_sy) on data row
    ``row`` and the others empty (aimed captures)."""

    def fn(d: Path):
        p = d / "sess/captures.csv"
        lines = p.read_text().splitlines()
        out = [lines[0] + ",camera_x,camera_y,camera_sx,camera_sy"]
        out += [ln + "," + (cells if i == row else ",,,") for i, ln in enumerate(lines[1:])]
        p.write_text("\n".join(out) + "\n")

    return fn


SESSION_BAD = {
    "captures camera_sx negative": (_spots("0,0,-0.1,0.1"), "camera_sx"),
    "captures camera_x nan": (_spots("nan,0,0.1,0.1"), "camera_x"),
    "captures spot partly empty": (_spots(",0,0.1,0.1"), "camera_x"),
    "captures spot uncertainty in metres-like text": (_spots("0,0,0.1,abc"), "camera_sy"),
    "captures spot far from its point": (_spots("5000,0,0.1,0.1"), "camera_x"),
    "session.yaml not utf-8": (_latin1("sess/session.yaml"), "session.yaml"),
    "captures not utf-8": (_latin1("sess/captures.csv"), "captures.csv"),
    "captures in degrees": (_degrees("sess/captures.csv", Q), "captures.csv"),
    "captures t nan": (_cell("sess/captures.csv", 3, "t", "nan"), "captures.csv"),
    "captures q inf": (_cell("sess/captures.csv", 3, "q2", "inf"), "captures.csv"),
    "captures unknown point": (_cell("sess/captures.csv", 0, "point", "P9"), "captures.csv"),
    "session aperture below the plane": (
        _yaml("sess/session.yaml", _set("laser", "aperture_z", -825.0)),
        "session.yaml",
    ),
    "session aperture nan": (_yaml("sess/session.yaml", _set("laser", "aperture_z", nan)), "session.yaml"),
    "session aperture in metres": (
        _yaml("sess/session.yaml", _set("laser", "aperture_z", 0.825)),
        "session.yaml",
    ),
    "session points in metres": (
        _yaml(
            "sess/session.yaml",
            lambda d: d.update(points={k: [c / 1000 for c in v] for k, v in d["points"].items()}),
        ),
        "session.yaml",
    ),
    "session units m": (_yaml("sess/session.yaml", _set("units", "length", "m")), "session.yaml"),
    "session plane z text": (_yaml("sess/session.yaml", _set("plane", "z", "low")), "session.yaml"),
    "session one capture at a point": (lambda d: _keep_only("sess/captures.csv", 25)(d), "P3"),
    "session collinear points": (
        _yaml("sess/session.yaml", lambda d: d["points"].__setitem__("P2", [521.0, 0.0, d["plane"]["z"]])),
        "collinear",
    ),
}
for cid, (setup, needle) in SESSION_BAD.items():
    case(f"solve: {cid}", SOLVE + ["-o", "{o}"], setup, needle)
for cid in ("session.yaml not utf-8", "captures in degrees", "session aperture below the plane"):
    case(f"diagnose: {cid}", DIAGNOSE, SESSION_BAD[cid][0], SESSION_BAD[cid][1])
    case(f"report: {cid}", REPORT + ["-o", "{o}"], SESSION_BAD[cid][0], SESSION_BAD[cid][1])

CONFIGS_BAD = {
    "configs not utf-8": _latin1("configs.csv"),
    "configs in degrees": _degrees("configs.csv", Q),
    "configs nan": _cell("configs.csv", 1, "q3", "nan"),
    "configs outside limits": _cell("configs.csv", 0, "q4", "1.0"),
    "configs missing column": lambda d: (d / "configs.csv").write_text("q1,q2\n0,0\n"),
}
for cid, setup in CONFIGS_BAD.items():
    case(f"predict: {cid}", PREDICT, setup, "configs.csv")

JUSTIN_BAD = {  # one record spoiled: its joints' array, its markers' array, a value
    "18 joint values": (1, "[" + " ".join(["0.1"] * 18) + "]", None),
    "one marker row": (1, None, '"[[-1.8  2.2  1.5]]"'),
    "a marker nan": (2, None, '"[[nan  2.2  1.5]\n [-3.0  1.6  1.8]]"'),
    "a joint text": (0, "[" + " ".join(["0.1"] * 18 + ["x"]) + "]", None),
}


def _justin_record(k: int, joints: str | None, markers: str | None):
    """The DLR file with record k's joints' or markers' array replaced."""
    records = [(i, joints or q, markers or mk) if i == k else (i, q, mk) for i, q, mk in JUSTIN_RECORDS]
    return lambda d: (d / "justin.csv").write_text(justin_text(records))


for cid, spoil in JUSTIN_BAD.items():
    case(f"import-justin: {cid}", JUSTIN_IMPORT + ["-o", "{o}"], _justin_record(*spoil), "justin.csv")


def _justin_units(deg: bool):
    """The DLR file as a converter would spoil it whole: every joint in degrees (poses across the joints'
    range, not the fixture's 0.1 rad, whose degrees 5.7 pass for radians), or every marker in mm."""

    def fn(d: Path):
        q = np.random.default_rng(7).uniform(-2.5, 2.5, (3, 19))
        mm = 1000.0 if not deg else 1.0
        records = [(k, "[" + " ".join(f"{v:.6e}" for v in (np.degrees(q[k]) if deg else q[k])) + "]",
                    f'"[[{-1.8 * mm:g}  {2.2 * mm:g}  {(1 + k / 10) * mm:g}]\n [{-3 * mm:g}  {1.6 * mm:g}  '
                    f'{1.8 * mm:g}]]"') for k in range(3)]  # fmt: skip
        (d / "justin.csv").write_text(justin_text(records))

    return fn


case("import-justin: joints in degrees", JUSTIN_IMPORT + ["-o", "{o}"], _justin_units(True),
     "justin.csv, line 2, column 'joints'", "silent")  # fmt: skip
case("import-justin: markers in millimetres", JUSTIN_IMPORT + ["-o", "{o}"], _justin_units(False),
     "justin.csv, line 2, column 'markers'", "silent")  # fmt: skip


def _ipa_cell(row: int, col: str, text: str):
    """The series file with one cell replaced (data row ``row``, 0-based)."""

    def fn(d: Path):
        p = d / "ipa" / "measurements_test.csv"
        lines = p.read_text().splitlines()
        head = lines[0].split(";")
        cells = lines[1 + row].split(";")
        cells[head.index(col)] = text
        lines[1 + row] = ";".join(cells)
        p.write_text("\n".join(lines) + "\n")

    return fn


IPA_BAD = {  # (setup, needle)
    "a joint angle text": (_ipa_cell(3, "elbow_joint", "abc"), "elbow_joint"),
    "a position blank": (_ipa_cell(5, "measurement_y", ""), "measurement_y"),
    "a joint angle in degrees": (_ipa_cell(2, "wrist_1_joint", "270,5"), "wrist_1_joint"),
    "a column missing": (lambda d: (d / "ipa/measurements_test.csv").write_text(
        (d / "ipa/measurements_test.csv").read_text().replace("measurement_rz", "rz")), "measurement_rz"),
    "no measurements file": (_rm("ipa/measurements_test.csv"), "measurements_*.csv"),
    "two measurements files": (_touch("ipa/measurements_more.csv", "a;b\n"), "measurements_"),
}  # fmt: skip
for cid, (setup, needle) in IPA_BAD.items():
    case(f"import-ipa: {cid}", IPA_IMPORT + ["-o", "{o}"], setup, needle)
POSES_BAD = {  # register's session and model, solve of pose sessions, predict of a pose model
    "register: rx in degrees": (REGISTER, _degrees("ps/captures.csv", ["rx", "ry", "rz"]), "rx"),
    "register: a laser model": (["register", "{d}/model.yaml", "{d}/ps"], None, "not a pose model"),
    "register: x nan": (REGISTER, _cell("ps/captures.csv", 2, "x", "nan"), "captures.csv"),
    "register: too few poses": (REGISTER, _keep_only("ps/captures.csv", 2), "poses"),
    "register: a laser session": (["register", "{d}/pmodel.yaml", "{d}/sess"], None, "measurement: pose"),
    "solve: a pose and a laser session": (["solve", "{d}/ps", "{d}/sess"], None, "sess"),
    "solve: two laser sessions": (["solve", "{d}/sess", "{d}/sess"], None, "pose sessions"),
    "solve: two pose sessions of one name": (["solve", "{d}/ps", "{d}/ps"], None, "folder name"),
    "solve: pose sessions --extend drift": (["solve", "{d}/ps", "--extend", "drift"], None, "--extend"),
    "predict: a pose model, configs without q6": (["predict", "{d}/pmodel.yaml", "{d}/pcfg.csv"],
        lambda d: (d / "pcfg.csv").write_text("q1,q2,q3,q4,q5\n0,0,0,0,0\n"), "q6"),
}  # fmt: skip
for cid, (argv, setup, needle) in POSES_BAD.items():
    case(cid, argv + ["-o", "{o}"], setup, needle)
case("register: positions in metres", REGISTER + ["-o", "{o}"], _metres("ps/captures.csv", ["x", "y", "z"]),
     "metres", "silent")  # fmt: skip

FP_BAD = {
    "fullpose not utf-8": _latin1("fp.csv"),
    "fullpose in metres": _metres("fp.csv", ["x", "y", "z"]),
    "fullpose in degrees": _degrees("fp.csv", Q),
    "fullpose x nan": _cell("fp.csv", 2, "x", "nan"),
    "fullpose angle index negative": _cell("fp.csv", 1, "angle_index", "-1"),
}
for cid, setup in FP_BAD.items():
    case(f"fullpose: {cid}", FULLPOSE + ["-o", "{o}"], setup, "fp.csv")

VAL_BAD = {
    "validation.csv not utf-8": (_latin1("val/validation.csv"), "validation.csv"),
    "validation x nan": (_cell("val/validation.csv", 0, "x_mm", "nan"), "validation.csv"),
    "validation in degrees": (_degrees("val/validation.csv", Q), "validation.csv"),
    "validation.yaml not utf-8": (_latin1("val/validation.yaml"), "validation.yaml"),
    "validation n negative": (_yaml("val/validation.yaml", _set("n", -3)), "validation.yaml"),
    "validation at a calibration point": (
        _yaml("val/validation.yaml", _set("point", {"name": "P1", "xyz": [521.0, 200.0, -8.0]})),
        "validation.yaml",
    ),
}
for cid, (setup, needle) in VAL_BAD.items():
    case(f"report: {cid}", REPORT + ["-o", "{o}"], setup, needle)
case("validate --point a calibration point", VALIDATE + ["-o", "{o}", "--point", "P1"], None, "P1")
case("validate --point unknown", VALIDATE + ["-o", "{o}", "--point", "P9"], None, "P9")
case("validate --resume not a run", ["validate", "--resume", "{d}/sess"], None, "sess")
case("validate --resume missing", ["validate", "--resume", "{d}/nothing"], None, "nothing")
REAL = ["validate", "{d}/model.yaml", "--backend", "franky", "--host", "192.0.2.1", "--camera", "0"]
case("validate real backend without --layout", REAL + ["-o", "{o}"], None, "--layout")
case("capture --hold on resume -1", ["capture", "--resume", "{d}/sess", "--hold", "-1"], None, "--hold")
case("capture --camera fake on a layout without markers", FAKE_CAPTURE + ["-o", "{o}", "--camera", "fake"],
     None, "markers")  # fmt: skip
case("capture --camera 7 absent", FAKE_CAPTURE + ["-o", "{o}", "--camera", "7"], None, "camera")
case("capture --effects on a real backend",
     ["capture", "--backend", "franky", "--host", "192.0.2.1", "--layout", "{d}/layout.yaml",
      "--per-point", "2", "-o", "{o}", "--effects", "all"], None, "--effects")  # fmt: skip

MUKCA_BAD = {
    "mukca missing hole file": (_rm("mukca/panda_1/front/hole_1.csv"), "hole_1.csv"),
    "mukca hole not utf-8": (_latin1("mukca/panda_1/front/hole_0.csv"), "hole_0.csv"),
    "mukca hole in degrees": (lambda d: _scale_all(d / "mukca/panda_1/front/hole_0.csv", 180 / np.pi),
                              "hole_0.csv"),
    "mukca hole nan": (lambda d: _replace_first_number(d / "mukca/panda_1/front/hole_0.csv", "nan"),
                       "hole_0.csv"),
    "mukca empty folder": (lambda d: shutil.rmtree(d / "mukca/panda_1/front"), "panda_1"),
}  # fmt: skip
for cid, (setup, needle) in MUKCA_BAD.items():
    case(f"import-mukca: {cid}", IMPORT + ["-o", "{o}"], setup, needle)
for cid in ("mukca missing hole file", "mukca hole not utf-8"):
    case(f"study-mukca: {cid}", STUDY + ["-o", "{o}"], MUKCA_BAD[cid][0], MUKCA_BAD[cid][1])


# --- 4. position sessions and robots from URDF (--robot on every command that reads a session) ---------
SOLVE_POS = ["solve", "{d}/pos", "--folds", "0", "-o", "{o}"]
BRANCHED = """<robot name="b"><link name="base"/><link name="a"/><link name="b"/>
<joint name="ja" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<joint name="jb" type="revolute"><parent link="base"/><child link="b"/><axis xyz="0 0 1"/>
<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"""


def _sensor_file(drop: int):
    """The session's x, y, z moved to pos/tracker.csv (``positions: tracker.csv``), ``drop`` rows short."""

    def fn(d: Path):
        lines = (d / "pos/captures.csv").read_text().splitlines()
        rows = [",".join(ln.split(",")[-4:]) for ln in lines[1 : len(lines) - drop]]
        (d / "pos/tracker.csv").write_text("\n".join(["target,x,y,z"] + rows) + "\n")
        _edit_yaml(d / "pos/session.yaml", _set("positions", "tracker.csv"))

    return fn


def _urdf_text(old: str, new: str):
    def fn(d: Path):
        p = d / "pos/arm.urdf"
        text = p.read_text()
        assert old in text
        p.write_text(text.replace(old, new, 1))

    return fn


POS_BAD = {
    "URDF not a chain": (_touch("pos/arm.urdf", BRANCHED), "arm.urdf"),
    "URDF missing": (_rm("pos/arm.urdf"), "pos/arm.urdf"),
    "URDF not XML": (_touch("pos/arm.urdf", "robot: ur5\n"), "arm.urdf"),
    "URDF revolute joint without limit": (
        lambda d: (d / "pos/arm.urdf").write_text(
            re.sub(r"<limit[^>]*/>", "", (d / "pos/arm.urdf").read_text(), count=1)
        ),
        "arm.urdf",
    ),
    "URDF zero axis": (_urdf_text('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), "arm.urdf"),
    "session tip_link not a link": (_yaml("pos/session.yaml", _set("tip_link", "tool9")), "tool9"),
    "positions in metres": (_metres("pos/captures.csv", ["x", "y", "z"]), "captures.csv"),
    "position x nan": (_cell("pos/captures.csv", 2, "x", "nan"), "captures.csv"),
    "position sigma negative": (
        lambda d: (d / "pos/captures.csv").write_text(
            "\n".join(
                [ln + (",sigma" if i == 0 else ",-0.01") for i, ln in enumerate(
                    (d / "pos/captures.csv").read_text().splitlines())]
            ) + "\n"
        ),
        "sigma",
    ),
    "position unknown target": (_cell("pos/captures.csv", 1, "target", "T9"), "T9"),
    "sensor rows one short": (_sensor_file(1), "tracker.csv"),
}  # fmt: skip
for cid, (setup, needle) in POS_BAD.items():
    case(f"solve: {cid}", SOLVE_POS, setup, needle)
for cid in ("URDF not a chain", "positions in metres", "sensor rows one short"):
    case(f"diagnose: {cid}", ["diagnose", "{d}/pos", "--bootstrap", "0"], POS_BAD[cid][0], POS_BAD[cid][1])
ROBOT_BAD = {
    "--robot a CSV": (["--robot", "{d}/configs.csv"], None, "configs.csv"),
    "--robot missing URDF": (["--robot", "{d}/nosuch.urdf"], None, "nosuch.urdf"),
    "--robot missing name": (["--robot", "nosuch_robot"], None, "nosuch_robot"),
    "--robot a layout": (["--robot", "{d}/layout.yaml"], None, "layout.yaml"),
    "--robot a xacro": (["--robot", "{d}/arm.urdf.xacro"], _touch("arm.urdf.xacro", "<robot/>"), "xacro"),
    "--robot URDF not a chain": (["--robot", "{d}/b.urdf"], _touch("b.urdf", BRANCHED), "b.urdf"),
    "--robot URDF, 7 joints for 6": (["--robot", str(URDF.parent / "rail_ur5.urdf")], None, "q7"),
    "--tip-link not a link": (["--tip-link", "tool9"], None, "tool9"),
    "--base-link below --tip-link": (["--base-link", "link6", "--tip-link", "link2"], None,
                                     "not below"),
    "--tip-link on a YAML robot": (["--robot", "panda", "--tip-link", "tool0"], None, "tip_link"),
}  # fmt: skip
for cid, (extra, setup, needle) in ROBOT_BAD.items():
    case(f"solve {cid}", SOLVE_POS + extra, setup, needle)
for cid in ("--robot a CSV", "--robot missing URDF", "--tip-link not a link"):
    extra, setup, needle = ROBOT_BAD[cid]
    case(f"diagnose {cid}", ["diagnose", "{d}/pos", "--bootstrap", "0"] + extra, setup, needle)
    case(f"plan {cid}", ["plan", "{d}/pos", "-o", "{o}"] + extra, setup, needle)
    case(f"report {cid}", ["report", "{d}/pos", "-o", "{o}"] + extra, setup, needle)
case(
    "fullpose --robot a CSV", FULLPOSE[:2] + ["--robot", "{d}/configs.csv", "-o", "{o}"], None, "configs.csv"
)
case("fullpose --robot URDF not a chain", FULLPOSE[:2] + ["--robot", "{d}/b.urdf", "-o", "{o}"],
     _touch("b.urdf", BRANCHED), "b.urdf")  # fmt: skip
case(
    "fullpose --robot URDF, 6 joints for 7",
    FULLPOSE[:2] + ["--robot", str(URDF), "-o", "{o}"],
    None,
    "fp.csv",
)
SIM_POS = ["simulate", "--measurement", "position", "-o", "{o}"]
SIMFP_URDF = ["simulate-fullpose", "--robot", "{d}/nosuch.urdf", "-o", "{o}"]
case("simulate-fullpose --robot missing URDF", SIMFP_URDF, None, "nosuch.urdf")
case(
    "simulate position: truth URDF not a chain",
    SIM_POS + ["{d}/b.urdf"],
    _touch("b.urdf", BRANCHED),
    "b.urdf",
)
case("simulate position --tip-link not a link", SIM_POS + [str(URDF), "--tip-link", "tool9"], None, "tool9")


# plan: a box inside out, a layout point out of reach, an output that exists
case("plan --workspace min > max", PLAN + ["-o", "{o}", "--workspace", "600", "0", "-8", "400", "300", "-8"],
     None, "workspace")  # fmt: skip
case("plan --workspace nan", PLAN + ["-o", "{o}", "--workspace", "nan", "0", "-8", "600", "300", "-8"], None,
     "workspace")  # fmt: skip
case("plan layout point out of reach", PLAN + ["-o", "{o}", "--layout", "{d}/layout.yaml"],
     _yaml("layout.yaml", _set("points", "P4", [2521.0, 160.0, -8.0])), "out of reach")  # fmt: skip
case("plan -o existing", PLAN + ["-o", "{d}/kept.csv"], _touch("kept.csv"), "--force")


# vision commands (their options; spot detection itself is another module's business)
CALIB = ["camera-calibrate", "{d}/val/photos/0000.png", "--chessboard", "9x6"]
for v in ("0", "-1", "nan"):
    case(f"camera-calibrate --square {v}", CALIB + ["--square", v, "-o", "{o}"], None, "--square")
case(
    "camera-calibrate -o existing",
    CALIB + ["--square", "20", "-o", "{d}/kept.yaml"],
    _touch("kept.yaml"),
    "--force",
)
case("spots --expect 0", ["spots", "{d}/val/photos/0000.png", "--expect", "0"], None, "--expect")
case(
    "beam-check --laser-length -1",
    ["beam-check", "{d}/val/photos/0000.png", "--laser-length", "-1"],
    None,
    "laser-length",
)

# sheet: the paper, lengths, a placement and a robot
SHEET = ["sheet", "-o", "{o}"]
SHEET_VALUES = {"--paper": ["A5", "0x200", "nanx200"], "--margin": ["-1", "nan"], "--marker": ["0", "inf"],
                "--plane-z": ["nan"]}  # fmt: skip
for opt, v in ((o, v) for o, vs in SHEET_VALUES.items() for v in vs):
    case(f"sheet {opt} {v}", SHEET + [opt, v], None, opt)
case("sheet paper too small for the bars", SHEET + ["--paper", "150x150"], None, "too small")
case("sheet --place nan", SHEET + ["--place", "nan", "0", "0"], None, "--place")
case("sheet --place two numbers", SHEET + ["--place", "450", "0"], None, "--place")
case("sheet --robot without --place", SHEET + ["--robot", "panda"], None, "--place")
case("sheet --robot unknown", SHEET + ["--robot", "nosuch", "--place", "450", "0", "0"], None, "nosuch")
case("sheet -o existing", ["sheet", "-o", "{d}/kept"], _mkdir("kept"), "--force")


# --- 5. the long tail (issue 26): files saved wrongly, units, degenerate data, every command -----------
BASE = {  # an argv of every command that parses and runs on the valid inputs (outputs left out)
    "demo": ["demo"],
    "capture": FAKE_CAPTURE,
    "solve": SOLVE,
    "plan": PLAN,
    "validate": VALIDATE,
    "report": REPORT,
    "export": EXPORT,
    "predict": PREDICT,
    "simulate": SIMULATE,
    "diagnose": DIAGNOSE,
    "spots": ["spots", "{d}/val/photos/0000.png"],
    "beam-check": ["beam-check", "{d}/val/photos/0000.png"],
    "camera-calibrate": CALIB + ["--square", "20"],
    "fullpose": FULLPOSE,
    "simulate-fullpose": SIMFP,
    "import-mukca": IMPORT,
    "import-justin": JUSTIN_IMPORT,
    "import-ipa": IPA_IMPORT,
    "register": REGISTER,
    "study-mukca": STUDY,
    "sheet": ["sheet"],
    "correct": ["correct", "{d}/model.yaml", "{d}/goals.csv"],
    "mujoco-scene": ["mujoco-scene", "--layout", "{d}/sheet/layout.yaml"],
    "new-session": ["new-session", "--layout", "{d}/sheet/layout.yaml"],
    "configurations": ["configurations", "{d}/model.yaml", "--layout", "{d}/layout.yaml"],
}
OUT = {"demo": "-o", "capture": "-o", "solve": "-o", "plan": "-o", "validate": "-o", "report": "-o",
       "export": "-o", "simulate": "-o", "diagnose": "--report", "camera-calibrate": "-o", "fullpose": "-o",
       "simulate-fullpose": "-o", "import-mukca": "-o", "import-justin": "-o", "study-mukca": "-o",
       "import-ipa": "-o", "register": "-o",
       "spots": "--overlay", "beam-check": "--overlay", "sheet": "-o", "correct": "-o",
       "mujoco-scene": "-o", "new-session": "-o", "configurations": "-o"}  # fmt: skip


def _argv(cmd: str) -> list:
    return BASE[cmd] + ([OUT[cmd], "{o}"] if cmd in OUT else [])


def _saved_as(rel: str, how: str):
    """The file ``rel`` saved wrongly: 'latin-1' (a Windows editor's ANSI), 'utf-16 without BOM',
    'binary', 'empty file', 'a folder for the file'."""

    def fn(d: Path):
        p = d / rel
        text = p.read_text()
        if how == "latin-1":
            p.write_bytes(("# caf\xe9 \xb0C\n" + text).encode("latin-1"))
        elif how == "utf-16 without BOM":
            p.write_bytes(text.encode("utf-16-le"))
        elif how == "binary":
            p.write_bytes(bytes(range(256)) * 4)
        elif how == "empty file":
            p.write_bytes(b"")
        else:
            p.unlink()
            p.mkdir()
            (p / "keep.txt").write_text("keep me\n")

    return fn


def _vision_file(rel: str, then):
    """A vision YAML (camera, markers layout) written first when ``rel`` is one, then ``then``."""

    def fn(d: Path):
        if rel in VISION_FILES:
            (d / rel).write_text("format: lasercal-layout/1\nunits: {length: mm}\n")
        then(d)

    return fn


# every text file each command reads, named in the message when saved wrongly; (file, the option giving it)
PRIOR_FILE = ("prior.yaml", ["--prior", "{d}/prior.yaml"])
INPUT_FILES = {
    "capture": ["layout.yaml"],
    "validate": ["layout.yaml", "model.yaml"],
    "simulate": ["layout.yaml"],
    "solve": ["sess/session.yaml", "sess/captures.csv", PRIOR_FILE],
    "plan": ["sess/session.yaml", "sess/captures.csv", PRIOR_FILE],
    "diagnose": ["sess/session.yaml", "sess/captures.csv", PRIOR_FILE],
    "report": ["sess/captures.csv", "val/validation.yaml", "val/validation.csv", PRIOR_FILE],
    "export": ["model.yaml"],
    "predict": ["model.yaml", "configs.csv"],
    "fullpose": ["fp.csv"],
    "import-mukca": ["mukca/panda_1/front/hole_0.csv"],
    "import-justin": ["justin.csv"],
    "import-ipa": ["ipa/measurements_test.csv"],
    "register": ["ps/session.yaml", "ps/captures.csv", "pmodel.yaml"],
    "study-mukca": ["mukca/panda_1/front/hole_1.csv", PRIOR_FILE],
    "spots": [("cam.yaml", ["--camera", "{d}/cam.yaml"]), ("markers.yaml", ["--layout", "{d}/markers.yaml"])],
    "beam-check": [("cam.yaml", ["--camera", "{d}/cam.yaml"])],
    "correct": ["model.yaml", "goals.csv"],
    "sheet": [("model.yaml", ["--robot", "{d}/model.yaml", "--place", "450", "0", "0"])],
}
SAVED_WRONGLY = ("latin-1", "utf-16 without BOM", "binary", "empty file", "a folder for the file")
VISION_FILES = ("cam.yaml", "markers.yaml")  # not among the valid inputs: written first, then spoiled
for cmd, files in INPUT_FILES.items():
    for rel, given in (f if isinstance(f, tuple) else (f, []) for f in files):
        for how in SAVED_WRONGLY:
            if how == "empty file" and cmd in ("spots", "beam-check"):
                continue  # an empty vision YAML is no layout and no camera: covered by the vision tests
            case(f"{cmd}: {rel} {how}", _argv(cmd) + given, _vision_file(rel, _saved_as(rel, how)),
                 rel.split("/")[-1], "traceback")  # fmt: skip


# files cut short, as a kill in the middle of a write or a partial copy leaves them: in the middle of a line
# (every file), and at a line end (YAML, which still parses: whole files say where they end, solver/whole.py)
def _torn(rel: str, at_line_end: bool = False):
    """``rel`` cut after the first comma (or line end) past its middle (else at it): cut short."""

    def fn(d: Path):
        p = d / rel
        data = p.read_bytes()
        mid = len(data) // 2
        p.write_bytes(data[: data.find(b"\n" if at_line_end else b",", mid) + 1 or mid])

    return fn


for cmd, files in INPUT_FILES.items():
    for rel, given in (f if isinstance(f, tuple) else (f, []) for f in files):
        if rel in VISION_FILES:
            continue  # written here by hand: a camera-calibrate's camera YAML is cut below
        ends = [False] + ([True] if rel.endswith(".yaml") and rel != "prior.yaml" else [])  # prior: by hand
        for at_end in ends:
            how = "truncated at a line end" if at_end else "torn mid-line"
            case(f"{cmd}: {rel} {how}", _argv(cmd) + given, _torn(rel, at_end), rel.split("/")[-1], "torn")
for at_end in (False, True):
    how = "truncated at a line end" if at_end else "torn mid-line"
    case(f"solve: a sheet session.yaml {how}", ["solve", "{d}/shs", "--folds", "0", "-o", "{o}"],
         _torn("shs/session.yaml", at_end), "shs/session.yaml", "torn")  # fmt: skip


def _cut_inside_requested(d: Path):
    """The issue's session.yaml, as written before files said where they end, cut inside 'requested:': its
    'frame: sheet' and 'sheet:' lines lost."""
    p = d / "shs/session.yaml"
    text = "".join(ln for ln in p.read_text().splitlines(keepends=True) if ln.rstrip() not in (WHOLE, "..."))
    p.write_text(text[: text.index("requested:") + len("requested:\n- P1\n- P")])


case("solve: a sheet session.yaml of old cut inside requested", ["solve", "{d}/shs", "--folds", "0", "-o",
     "{o}"], _cut_inside_requested, "shs/session.yaml", "torn")  # fmt: skip


# a folder where a file is expected and the other way round, for every path argument
KINDS = [
    ("solve", ["solve", "{d}/model.yaml", "-o", "{o}"], "is a file"),
    ("plan", ["plan", "{d}/configs.csv"], "is a file"),
    ("diagnose", ["diagnose", "{d}/configs.csv"], "is a file"),
    ("report", ["report", "{d}/sess", "{d}/fp.csv", "-o", "{o}"], "is a file"),
    ("import-mukca", ["import-mukca", "{d}/fp.csv", "-o", "{o}"], "is a file"),
    ("study-mukca", ["study-mukca", "{d}/fp.csv", "-o", "{o}"], "is a file"),
    ("capture", ["capture", "--resume", "{d}/fp.csv"], "is a file"),
    ("validate", ["validate", "--resume", "{d}/fp.csv"], "is a file"),
    ("predict", ["predict", "{d}/model.yaml", "{d}/sess"], "is a folder"),
    ("predict", ["predict", "{d}/sess", "{d}/configs.csv"], "sess"),
    ("export", ["export", "{d}/val", "-o", "{o}"], "val"),
    ("fullpose", ["fullpose", "{d}/sess", "--robot", "panda", "-o", "{o}"], "is a folder"),
    ("simulate", SIMULATE[:2] + ["--layout", "{d}/sess", "-o", "{o}"], "sess"),
    ("simulate-fullpose", ["simulate-fullpose", "--robot", "{d}/sess", "-o", "{o}"], "sess"),
    ("validate", VALIDATE[:4] + ["--layout", "{d}/val", "-o", "{o}"], "val"),
    ("spots", ["spots", "{d}/val/photos/0000.png", "--reference", "{d}/val"], "is a folder"),
    ("spots", ["spots", "{d}/val/photos/0000.png", "--camera", "{d}/val"], "is a folder"),
    ("correct", ["correct", "{d}/sess", "{d}/goals.csv", "-o", "{o}"], "is a folder"),
    ("correct", ["correct", "{d}/model.yaml", "{d}/sess", "-o", "{o}"], "is a folder"),
    ("sheet", ["sheet", "--robot", "{d}/sess", "--place", "450", "0", "0", "-o", "{o}"], "is a folder"),
    ("solve", ["solve", "--prior", "{d}/val", "{d}/sess", "-o", "{o}"], "is a folder"),
    ("beam-check", ["beam-check", "{d}/val/photos/0000.png", "--layout", "{d}/sess"], "sess"),
]  # fmt: skip
for cmd, argv, needle in KINDS:
    case(f"{cmd}: a folder for a file or a file for a folder: {' '.join(argv[1:3])}", argv, None, needle,
         "traceback")  # fmt: skip

# values in the wrong units, in every mm and rad column (they used to pass, or fail late)
UNITS_BAD = [
    ("report", "validation x_mm, y_mm in metres", _metres("val/validation.csv", ["x_mm", "y_mm"]), "x_mm"),
    ("fullpose", "pose origins in metres", _metres("poses.csv", ["x", "y", "z"]), "poses.csv"),
    ("plan", "captures in degrees", _degrees("sess/captures.csv", Q), "captures.csv"),
    ("validate", "layout in metres", LAYOUT_BAD["layout in metres"], "layout.yaml"),
    ("capture", "layout units m", LAYOUT_BAD["layout units m"], "layout.yaml"),
    ("predict", "model aperture in metres", MODEL_BAD["model aperture in metres"], "model.yaml"),
    ("export", "model limits in degrees", MODEL_BAD["model limits in degrees"], "model.yaml"),
    ("import-mukca", "hole in degrees", MUKCA_BAD["mukca hole in degrees"][0], "hole_0.csv"),
    ("study-mukca", "hole in degrees", MUKCA_BAD["mukca hole in degrees"][0], "hole_0.csv"),
    ("diagnose", "positions in metres", POS_BAD["positions in metres"][0], "captures.csv"),
]
for cmd, cid, setup, needle in UNITS_BAD:
    argv = _argv(cmd)
    if cid == "pose origins in metres":
        argv = ["fullpose", "{d}/poses.csv", "--robot", "panda", "-o", "{o}"]
    elif cid == "positions in metres":
        argv = ["diagnose", "{d}/pos", "--bootstrap", "0"]
    case(f"{cmd}: {cid}", argv, setup, needle, "silent")
for v, needle in (("0", "--gamma"), ("nan", "--gamma"), ("-1", "--imagej-box")):
    opt = needle
    case(f"spots {opt} {v}", ["spots", "{d}/val/photos/0000.png", opt, v], None, opt, "silent")
for v in ("nan", "0.3"):  # 0.3: metres
    case(f"beam-check --laser-length {v}", BASE["beam-check"] + ["--laser-length", v], None, "--laser-length",
         "silent")  # fmt: skip
case("camera-calibrate --square 0.02 (metres)", CALIB + ["--square", "0.02", "-o", "{o}"], None, "--square",
     "silent")  # fmt: skip
case("simulate-fullpose --radius 0.05 (metres)", SIMFP + ["--radius", "0.05", "-o", "{o}"], None, "--radius",
     "silent")  # fmt: skip


def _half_position(d: Path):
    shutil.copytree(d / "mukca/panda_1/front", d / "mukca/panda_1/back")
    (d / "mukca/panda_1/back/hole_1.csv").unlink()


case("import-mukca: a tool position with one hole file", _argv("import-mukca"), _half_position,
     "back/hole_1.csv", "silent")  # fmt: skip
case("predict: a measured angle far beyond its limit (wrong column)", PREDICT,
     _cell("configs.csv", 0, "q1", "3.2"), "configs.csv", "culprit")  # fmt: skip


MARKERS_M = """format: lasercal-layout/1
markers:
  dictionary: DICT_4X4_50
  ids:
    0: [[0.0, 0.02], [0.02, 0.02], [0.02, 0.0], [0.0, 0.0]]
"""
case("plan --workspace in metres", PLAN + ["--workspace", "0.4", "0", "0", "0.6", "0.3", "0"], None,
     "--workspace", "silent")  # fmt: skip
case("simulate-fullpose --step 0.35 (radians)", SIMFP + ["--step", "0.35", "-o", "{o}"], None, "--step",
     "silent")  # fmt: skip
case("export: tool point in metres", _argv("export"),
     _yaml("model.yaml", _set("tool", {"point": [0.088, 0, 0.79]})), "tool.point", "silent")  # fmt: skip
case("spots: marker corners in metres", ["spots", "{d}/val/photos/0000.png", "--layout", "{d}/m.yaml"],
     _touch("m.yaml", MARKERS_M), "m.yaml", "silent")  # fmt: skip
case("predict: configs.csv a header and no rows", PREDICT, _keep_only("configs.csv", 0), "configs.csv",
     "culprit")  # fmt: skip
case("solve: captures.csv a header and no rows", _argv("solve"), _keep_only("sess/captures.csv", 0),
     "captures.csv", "culprit")  # fmt: skip
case("solve --folds more than captures", SOLVE[:2] + ["--folds", "1000", "-o", "{o}"], None, "--folds",
     "culprit")  # fmt: skip
case("export: model number 1e308", _argv("export"),
     _yaml("model.yaml", _set("laser", "M", [0.0, 0.0, 1e308])), "model.yaml", "culprit")  # fmt: skip
case("report: validation point xyz blank", _argv("report"),
     _yaml("val/validation.yaml", _set("point", "xyz", [None, None, None])), "validation.yaml",
     "culprit")  # fmt: skip
case("solve: captures.csv separated by semicolons", _argv("solve"),
     lambda d: (d / "sess/captures.csv").write_text((d / "sess/captures.csv").read_text().replace(",", ";")),
     "captures.csv", "traceback")  # fmt: skip


case("capture --trigger unknown (unused with --auto, checked all the same)",
     _argv("capture") + ["--trigger", "foot"], None, "--trigger", "culprit")  # fmt: skip
case("capture --aperture-z 200 mm from the model's", _argv("capture") + ["--aperture-z", "625"], None,
     "--aperture-z", "silent")  # fmt: skip
case("validate --camera frames that are not there", _argv("validate") + ["--camera", "{d}/frames/%04d.png"],
     None, "frames/%04d.png", "culprit")  # fmt: skip
PHOTO = "{d}/val/photos/0000.png"
case("beam-check: the same photo twice", ["beam-check", PHOTO, "{d}/val/photos/0001.png", PHOTO], None,
     "same photo", "degenerate")  # fmt: skip


FAR = [2521.0, 160.0, -8.0]  # 2.5 m from the base: no Panda reaches it
for cmd, argv, pt in (("simulate", _argv("simulate"), "P1"), ("capture", _argv("capture"), "P2"),
                      ("validate", ["validate", "panda"] + _argv("validate")[2:], "P4"),
                      ("plan", PLAN + ["--layout", "{d}/layout.yaml"], "P4")):  # fmt: skip
    case(f"{cmd}: layout point {pt} out of reach", argv, _yaml("layout.yaml", _set("points", pt, FAR)),
         f"layout.yaml, point {pt}", "culprit")  # fmt: skip


case("solve: URDF lengths in mm", SOLVE_POS, _urdf_text('xyz="0 0 0.089159"', 'xyz="0 0 89.159"'), "arm.urdf",
     "silent")  # fmt: skip


# input that makes the problem degenerate, named as such before the fit
def _copies(rel: str, point: str | None = None):
    """Every capture (at ``point``, or at each point) replaced by the first one there: copies."""

    def fn(d: Path):
        lines = (d / rel).read_text().splitlines()
        first = {}
        for i, ln in enumerate(lines[1:], 1):
            nm = ln.split(",")[0]
            first.setdefault(nm, ln)
            if point in (None, nm):
                lines[i] = first[nm]
        (d / rel).write_text("\n".join(lines) + "\n")

    return fn


def _coincident(rel: str, names=("P1", "P2", "P3")):
    return _yaml(rel, lambda d: [d["points"].__setitem__(n, list(d["points"][names[0]])) for n in names[1:]])


def _distance(value):
    return _yaml("pt/session.yaml", lambda d: d["constraints"]["distances"][0].__setitem__(2, value))


DEGENERATE = [
    ("solve", SOLVE, "every capture a copy of the first", _copies("sess/captures.csv"), "distinct"),
    ("diagnose", DIAGNOSE, "captures at P2 copies of one", _copies("sess/captures.csv", "P2"), "P2"),
    ("report", REPORT, "captures at P3 copies of one", _copies("sess/captures.csv", "P3"), "P3"),
    ("plan", PLAN, "every capture a copy", _copies("sess/captures.csv"), "distinct"),
    ("solve", SOLVE, "three coincident points", _coincident("sess/session.yaml"), "same point"),
    ("diagnose", DIAGNOSE, "three coincident points", _coincident("sess/session.yaml"), "same point"),
    ("plan", PLAN, "two coincident points", _coincident("sess/session.yaml", ("P1", "P3")), "same point"),
    ("report", REPORT, "three coincident points", _coincident("sess/session.yaml"), "same point"),
    ("simulate", SIMULATE, "three coincident layout points", _coincident("layout.yaml"), "same point"),
    ("capture", FAKE_CAPTURE, "coincident points", _coincident("layout.yaml", ("P2", "P3")), "same point"),
    ("validate", VALIDATE, "coincident points", _coincident("layout.yaml", ("P1", "P4")), "same point"),
    ("simulate", SIMULATE, "a point both calibration and validation",
     _yaml("layout.yaml", _set("validation", ["P4", "P2"])), "both"),
    ("capture", FAKE_CAPTURE, "a point both calibration and validation",
     _yaml("layout.yaml", _set("validation", ["P1"])), "both"),
    ("solve", ["solve", "{d}/pt", "--folds", "0"], "known distance 0", _distance(0), "distance"),
    ("solve", ["solve", "{d}/pt", "--folds", "0"], "known distance negative", _distance(-50), "distance"),
    ("diagnose", ["diagnose", "{d}/pt", "--bootstrap", "0"], "known distance nan", _distance(nan),
     "distance"),
    ("solve", ["solve", "{d}/pt", "--folds", "0"], "known distance from a point to itself",
     _yaml("pt/session.yaml", lambda d: d["constraints"]["distances"][0].__setitem__(1, "front/hole_0")),
     "itself"),
    ("solve", ["solve", "{d}/pt", "--folds", "0"], "unknown points and no known distance",
     _yaml("pt/session.yaml", _set("constraints", {})), "no known distance"),
]  # fmt: skip
for cmd, argv, cid, setup, needle in DEGENERATE:
    argv = argv + ([OUT[cmd], "{o}"] if cmd in OUT and OUT[cmd] not in argv else [])
    case(f"{cmd}: {cid}", argv, setup, needle, "degenerate")


# --- 6. every declared output path of every command (options.output_argument) -----------------------
def _subparser(name: str):
    sub = next(a for a in build_parser(name)._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


def declared_outputs(name: str) -> list:
    """(dest, option, kind, instead) of each output path the command declares."""
    return list(_subparser(name).get_default("_outputs") or [])


for cmd in BASE:
    for _dest, flag, kind, _instead in declared_outputs(cmd):
        base_argv = [a for a in _argv(cmd) if a != "{o}" and a != OUT.get(cmd)]

        def out(path, base_argv=base_argv, flag=flag):
            return base_argv + [flag, path]

        case(f"{cmd} {flag} in a missing folder", out("{d}/no/such/dir/out"), None, flag, "output")
        case(f"{cmd} {flag} below a file", out("{d}/afile/out"), _touch("afile"), flag, "output")
        case(f"{cmd} {flag} on a read-only file system", out("/sys/lasercal-out"), None, "cannot write",
             "output")  # fmt: skip
        case(f"{cmd} {flag} empty", out(""), None, flag, "output")
        if kind == "file":
            if "--force" in _subparser(cmd)._option_string_actions:
                case(f"{cmd} {flag} an existing file", out("{d}/kept.out"), _touch("kept.out"), "--force",
                     "output")  # fmt: skip
            case(f"{cmd} {flag} an existing folder", out("{d}/adir"), _mkdir("adir"), flag, "output")
        else:
            case(f"{cmd} {flag} an existing file", out("{d}/afile"), _touch("afile"), flag, "output")
            if kind == "folder":
                case(f"{cmd} {flag} a folder in use", out("{d}/kept"), _mkdir("kept"), "kept", "output")


# an output that is one of the inputs, or the other output, is refused even with --force
for cmd, argv, needle in (
    ("fullpose", FULLPOSE + ["-o", "{d}/fp.csv", "--force"], "replace the input"),
    ("export", EXPORT + ["--format", "yaml", "-o", "{d}/model.yaml", "--force"], "replace the input"),
    ("report", REPORT + ["-o", "{d}/sess", "--force"], "replace the input"),
    ("simulate-fullpose", ["simulate-fullpose", "--robot", "{d}/model.yaml", "-o", "{d}/model.yaml",
                           "--force"], "replace the input"),
    ("camera-calibrate", CALIB + ["--square", "20", "-o", "{d}/val/photos/0000.png", "--force"],
     "replace the input"),
    ("export", EXPORT + ["-o", "{d}/m.urdf", "--sensor-output", "{d}/m.urdf"], "the same path"),
    ("export", EXPORT + ["--format", "franka", "-o", "{d}/model.yaml", "--force"], "replace the input"),
    ("correct", BASE["correct"] + ["-o", "{d}/goals.csv", "--force"], "replace the input"),
):  # fmt: skip
    case(f"{cmd}: an output that is an input: {' '.join(argv[-3:])}", argv, None, needle, "output")
case("demo -o an existing file named demo (the command's name is no input)", ["demo", "-o", "{d}/demo"],
     _touch("demo"), "is a file", "output")  # fmt: skip


# every command's every output on one of its inputs, with --force: the input itself, a symbolic link to it, a
# file inside an input folder, a folder holding an input, a file written into a folder that is an input
HOLE = "mukca/panda_1/front/hole_0.csv"
IN_FOLDER = {"sess": "sess/captures.csv", "val": "val/validation.csv", "mukca": HOLE, "mukca/panda_1": HOLE}


def _link(rel: str, to: str, hard: bool = False):
    return lambda d: os.link(d / to, d / rel) if hard else (d / rel).symlink_to(d / to)


def _overlay_inputs(d: Path):
    (d / "ph").mkdir()
    for name in ("a.png", "a.overlay.png"):
        shutil.copy(d / "val/photos/0000.png", d / "ph" / name)


def _onto_inputs(cmd: str, flag: str, kind: str):
    """(how, argv, setup) of each way the output ``flag`` of ``cmd`` can land on one of its inputs."""
    argv = [a for a in _argv(cmd) if a != "{o}" and a != OUT.get(cmd)]
    if "--force" in _subparser(cmd)._option_string_actions:
        argv = argv + ["--force"]
    given = next((a[len("{d}/") :] for a in argv if a.startswith("{d}/")), None)
    if kind == "into":
        if cmd == "diagnose":
            yield "a plot named like its --prior", argv + ["--prior", "{d}/before_after.png", flag, "{d}"], \
                _touch("before_after.png", PRIOR)  # fmt: skip
        else:
            photos = ["{d}/ph/a.png", "{d}/ph/a.overlay.png"]
            argv = [cmd] + photos + argv[2:] + [flag, "{d}/ph"]
            yield "an overlay named like a photo", argv, _overlay_inputs
        return
    if given is None:
        return
    if kind == "file":
        inside = IN_FOLDER.get(given)
        yield "the input", argv + [flag, "{d}/" + (inside or given)], None
        yield "a link to the input", argv + [flag, "{d}/link"], _link("link", inside or given)
        yield "a hard link to the input", argv + [flag, "{d}/hard"], _link("hard", inside or given, hard=True)
    else:
        yield "the folder holding the input", argv + [flag, "{d}"], None
        if given in IN_FOLDER:
            yield "the input folder", argv + [flag, "{d}/" + given], None
            sub = given + "/sub"
            yield "a folder inside the input folder", argv + [flag, "{d}/" + sub], _mkdir(sub)


for cmd in BASE:
    for _dest, flag, kind, _instead in declared_outputs(cmd):
        for how, argv, setup in _onto_inputs(cmd, flag, kind):
            case(f"{cmd} {flag} onto an input, --force: {how}", argv, setup, "would replace", "output")


def _data_lines(path: Path):
    lines = path.read_text().splitlines()
    return lines, [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")]


def _scale_all(path: Path, factor: float) -> None:
    lines, idx = _data_lines(path)
    for i in idx:
        lines[i] = ",".join(repr(float(c) * factor) for c in lines[i].split(","))
    path.write_text("\n".join(lines) + "\n")


def _replace_first_number(path: Path, text: str) -> None:
    lines, idx = _data_lines(path)
    cells = lines[idx[0]].split(",")
    cells[0] = text
    lines[idx[0]] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


# --- lasercal correct: its options, its goals file, its model ----------------------------------------------
CORRECT = ["correct", "{d}/model.yaml", "{d}/configs.csv", "-o", "{o}"]
for opt, values in {
    "--margin": ["-1", "nan", "1"],
    "--restarts": ["-1", "1.5"],
    "--tcp": ["nan"],
    "--payload": ["1,2", "0,0,0,0"],
}.items():
    for v in values:
        case(f"correct {opt} {v}", CORRECT + [opt] + ([v, "0", "0"] if opt == "--tcp" else [v]), None, opt)
case("correct: program in degrees", CORRECT, _degrees("configs.csv", Q), "configs.csv")
case("correct: program value nan", CORRECT, _cell("configs.csv", 0, "q2", "nan"), "configs.csv")
case("correct: unknown tool", CORRECT + ["--tool", "T9"], None, "--tool")
case("correct: model payload mass text", CORRECT,
     _yaml("model.yaml", _set("identification", "payload", {"mass": "heavy", "com": [0, 0, 900]})),
     "identification.payload")  # fmt: skip
case(
    "correct: no nominal",
    CORRECT,
    _yaml("model.yaml", _set("name", "mybot"), lambda m: m.pop("nominal"), lambda m: m.pop("identification")),
    "nominal",
)


# --- 9. beside issue 26: sheet, correct's goals, --prior files, --sheet-pose, sheet layouts and sessions ----
SIM_SHEET = ["simulate", "panda_thesis_identified", "--layout", "{d}/sheet/layout.yaml", "--per-point", "3"]
PLACE = ["--place", "450", "0", "0"]
case("sheet --place 0.45 0 0 (metres)", SHEET + ["--place", "0.45", "0", "0"], None, "--place", "silent")
case("sheet --place yaw beyond a turn", SHEET + ["--place", "450", "0", "400"], None, "--place")
case("sheet --robot a layout", SHEET + ["--robot", "{d}/layout.yaml"] + PLACE, None, "layout.yaml")
case("sheet --robot URDF not a chain", SHEET + ["--robot", "{d}/b.urdf"] + PLACE, _touch("b.urdf", BRANCHED),
     "b.urdf")  # fmt: skip
case("sheet --tip-link not a link", SHEET + ["--robot", str(URDF), "--tip-link", "tool9"] + PLACE, None,
     "tool9")  # fmt: skip

# lasercal correct's goals (IN.csv): the file, line and column named
GOALS_BAD = [
    ("a goal x nan", "x,y,z\nnan,0,500\n", "line 2, column 'x'", "culprit"),
    ("a goal z inf", "x,y,z\n400,0,500\n400,0,inf\n", "line 3, column 'z'", "culprit"),
    ("goals in metres", "x,y,z\n0.4,0,0.5\n0.45,0.02,0.48\n", "line 2, column 'x'", "silent"),
    ("one goal in metres among mm", "x,y,z\n400,0,500\n0.45,0.02,0.48\n", "line 3, column 'x'", "silent"),
    ("column z missing", "x,y\n400,0\n", "line 1, column 'z'", "culprit"),
    ("column x twice", "x,y,z,x\n400,0,500,1\n", "line 1, column 'x'", "silent"),
    ("columns in capitals", "X,Y,Z\n400,0,500\n", "line 1", "culprit"),
    ("a row one value short", "x,y,z\n400,0,500\n400,0\n", "line 3", "culprit"),
    ("seeds q1..q3 of 7 joints", "x,y,z,q1,q2,q3\n400,0,500,0,0,0\n", "line 1, column 'q4'", "culprit"),
    ("a program q1..q8 for 7 joints", "q1,q2,q3,q4,q5,q6,q7,q8\n0,0,0,-1,0,1,0,0\n", "line 1, column 'q8'",
     "silent"),
    ("a program one joint short", "q1,q2,q3,q4,q5,q6\n0,0,0,-1,0,1\n", "line 1, column 'q7'", "culprit"),
    ("rotation vector in degrees", "x,y,z,rx,ry,rz\n400,0,500,180,0,0\n", "line 2, column 'rx'", "silent"),
    ("rotation without a position", "rx,ry,rz,q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,0,0,-1,0,1,0\n",
     "line 1, column 'rx'", "culprit"),
    ("rotation two columns of three", "x,y,z,rx,ry\n400,0,500,1,0\n", "line 1, column 'rz'", "culprit"),
    ("separated by semicolons", "x;y;z\n400;0;500\n", "line 1", "traceback"),
    ("a header and no rows", "x,y,z\n", "line 1: no goals", "culprit"),
]  # fmt: skip
for cid, text, where, cat in GOALS_BAD:
    case(f"correct: goals.csv {cid}", _argv("correct"), _touch("goals.csv", text), f"goals.csv, {where}", cat)
case("correct --tcp 0.01 0 0.1 (metres)", _argv("correct") + ["--tcp", "0.01", "0", "0.1"], None, "--tcp",
     "silent")  # fmt: skip
case("correct --tool blank", _argv("correct") + ["--tool", " "], None, "--tool")
case("correct: a robot name that is none", ["correct", "nosuch_robot", "{d}/goals.csv", "-o", "{o}"], None,
     "nosuch_robot")  # fmt: skip

# --prior FILE (lasercal-prior/1) on every command that fits: the file and the field named
PRIOR_BAD = [
    ("not a mapping", "- offset_mm\n- 4.0\n", "field 'format'", "culprit"),
    ("format missing", "prior: {offset_mm: 4.0}\n", "field 'format'", "culprit"),
    ("a robot model's format", "format: lasercal-robot/1\nprior: {offset_mm: 4.0}\n", "field 'format'",
     "culprit"),
    ("units a word", "format: lasercal-prior/1\nunits: mm\nprior: {offset_mm: 4.0}\n", "field 'units'",
     "traceback"),
    ("units m", "format: lasercal-prior/1\nunits: {length: m}\nprior: {offset_mm: 4.0}\n", "field 'units'",
     "silent"),
    ("a tolerance outside prior:", "format: lasercal-prior/1\noffset_mm: 4.0\n", "field 'offset_mm'",
     "silent"),
    ("prior: misspelt", "format: lasercal-prior/1\npriors: {offset_mm: 4.0}\n", "field 'priors'", "silent"),
    ("unknown tolerance", "format: lasercal-prior/1\nprior: {offset: 4.0}\n", "field 'prior.offset'",
     "culprit"),
    ("tolerance zero", "format: lasercal-prior/1\nprior: {offset_mm: 0}\n", "field 'prior.offset_mm'",
     "culprit"),
    ("tolerance negative", "format: lasercal-prior/1\nprior: {tool_mm: -5}\n", "field 'prior.tool_mm'",
     "culprit"),
    ("tolerance nan", "format: lasercal-prior/1\nprior: {axis_rad: .nan}\n", "field 'prior.axis_rad'",
     "culprit"),
    ("tolerance yes", "format: lasercal-prior/1\nprior: {offset_mm: yes}\n", "field 'prior.offset_mm'",
     "silent"),
    ("tolerance with its unit", "format: lasercal-prior/1\nprior: {offset_mm: 4 mm}\n",
     "field 'prior.offset_mm'", "culprit"),
    ("noise_mm a number", "format: lasercal-prior/1\nprior: {noise_mm: 1.0}\n", "field 'prior.noise_mm'",
     "culprit"),
    ("noise_mm of an unknown measurement", "format: lasercal-prior/1\nprior: {noise_mm: {tracker: 0.1}}\n",
     "field 'prior.noise_mm'", "culprit"),
    ("noise_mm infinite", "format: lasercal-prior/1\nprior: {noise_mm: {laser: .inf}}\n",
     "field 'prior.noise_mm.laser'", "culprit"),
    ("noise_dof infinite", "format: lasercal-prior/1\nprior: {noise_dof: .inf}\n", "field 'prior.noise_dof'",
     "culprit"),
    ("prior a list", "format: lasercal-prior/1\nprior: [4.0, 0.01]\n", "field 'prior'", "culprit"),
    ("invalid YAML", "format: lasercal-prior/1\nprior: {offset_mm: 4.0\n", "line 3", "culprit"),
]  # fmt: skip
FITS = ("solve", "plan", "diagnose", "report", "study-mukca")
for i, (cid, text, where, cat) in enumerate(PRIOR_BAD):
    for cmd in FITS if i < 3 else ("solve", FITS[1 + i % 4]):  # every case on solve, a few on the others
        case(f"{cmd}: prior.yaml {cid}", _argv(cmd) + ["--prior", "{d}/prior.yaml"],
             _touch("prior.yaml", text), f"prior.yaml, {where}", cat)  # fmt: skip
for cmd in FITS:
    case(f"{cmd} --prior a file that is not there", _argv(cmd) + ["--prior", "{d}/no.yaml"], None, "--prior")
case("solve --prior blank", _argv("solve") + ["--prior", ""], None, "--prior")

# simulate --sheet-pose X Y YAW (mm, mm, deg); NaN and inf by its declared range (section 7)
case("simulate --sheet-pose a displacement out of reach", _argv("simulate") + ["--sheet-pose", "2000", "0",
     "0"], None, "layout.yaml, point")  # fmt: skip
case("simulate --sheet-pose yaw beyond a turn", _argv("simulate") + ["--sheet-pose", "5", "5", "720"], None,
     "--sheet-pose")  # fmt: skip
case("simulate --sheet-pose 0.455 0.005 2 on a sheet layout (metres)", SIM_SHEET + ["-o", "{o}",
     "--sheet-pose", "0.455", "0.005", "2"], None, "--sheet-pose", "silent")  # fmt: skip


# layouts and sessions with frame: sheet (points in the sheet's own frame), and a model's sheet pose
def _sheet_yaml(rel: str, *keys_value):
    """An edit of the sheet's layout or session: _sheet_yaml('layout', 'sheet', 'x_mm', nan)."""
    return _yaml({"layout": "sheet/layout.yaml", "session": "shs/session.yaml"}[rel], _set(*keys_value))


def _drop_frame(rel: str):
    return _yaml(rel, lambda d: d.pop("frame"))


def _sheet_point_z(rel: str, name: str):
    return _yaml(rel, lambda d: d["points"][name].__setitem__(2, -8.0))  # the plane's z, not the sheet's 0


SHEET_LAYOUT_BAD = [
    ("frame unknown", _sheet_yaml("layout", "frame", "paper"), "frame", "culprit"),
    ("a placement without frame: sheet", _drop_frame("sheet/layout.yaml"), "sheet", "culprit"),
    ("placement keys x, y", _sheet_yaml("layout", "sheet", {"x": 450, "y": 0}), "sheet", "culprit"),
    ("placement a list", _sheet_yaml("layout", "sheet", [450, 0, 0]), "sheet", "culprit"),
    ("placement x nan", _sheet_yaml("layout", "sheet", "x_mm", nan), "sheet.x_mm", "culprit"),
    ("placement yaw text", _sheet_yaml("layout", "sheet", "yaw_deg", "left"), "sheet.yaw_deg", "culprit"),
    ("placement yaw beyond a turn", _sheet_yaml("layout", "sheet", "yaw_deg", 400.0), "sheet.yaw_deg",
     "culprit"),
    ("placement in metres", _sheet_yaml("layout", "sheet", {"x_mm": 0.45, "y_mm": 0.0}), "sheet", "silent"),
    ("a point at the plane's z", _sheet_point_z("sheet/layout.yaml", "P1"), "points.P1", "culprit"),
    ("points in metres", _yaml("sheet/layout.yaml", lambda d: d.update(
        points={k: [c / 1000 for c in v] for k, v in d["points"].items()})), "points", "silent"),
]  # fmt: skip
CAPTURE_SHEET = FAKE_CAPTURE[:4] + ["--per-point", "2", "--layout", "{d}/sheet/layout.yaml", "-o", "{o}"]
VALIDATE_SHEET = VALIDATE[:-2] + ["--layout", "{d}/sheet/layout.yaml", "-o", "{o}"]
for i, (cid, setup, field, cat) in enumerate(SHEET_LAYOUT_BAD):
    needle = f"layout.yaml, field '{field}'"
    case(f"simulate: a sheet layout's {cid}", SIM_SHEET + ["-o", "{o}"], setup, needle, cat)
    case(f"{('capture', 'validate')[i % 2]}: a sheet layout's {cid}", (CAPTURE_SHEET, VALIDATE_SHEET)[i % 2],
         setup, needle, cat)  # fmt: skip
SHEET_SESSION_BAD = [
    ("frame unknown", _sheet_yaml("session", "frame", "table"), "frame", "culprit"),
    ("a placement without frame: sheet", _drop_frame("shs/session.yaml"), "sheet", "culprit"),
    ("placement x nan", _sheet_yaml("session", "sheet", "x_mm", nan), "sheet.x_mm", "culprit"),
    ("placement in metres", _sheet_yaml("session", "sheet", {"x_mm": 0.455, "y_mm": 0.005}), "sheet",
     "silent"),
    ("a point off the sheet", _sheet_point_z("shs/session.yaml", "P2"), "points.P2", "culprit"),
]  # fmt: skip
SHEET_FITS = (["solve", "{d}/shs", "--folds", "0", "-o", "{o}"], ["diagnose", "{d}/shs", "--bootstrap", "0"])
for i, (cid, setup, field, cat) in enumerate(SHEET_SESSION_BAD):
    argv = SHEET_FITS[i % 2]
    case(f"{argv[0]}: a sheet session's {cid}", argv, setup, f"session.yaml, field '{field}'", cat)
case("solve: a sheet session with --method thesis", ["solve", "{d}/shs", "--method", "thesis", "-o", "{o}"],
     None, "the thesis method needs the reference points in the base frame")  # fmt: skip
case("validate: a sheet layout and a model without a sheet pose", ["validate", "panda", "--backend", "fake",
     "-n", "3", "--layout", "{d}/sheet/layout.yaml", "-o", "{o}"], None, "no sheet pose")  # fmt: skip
SHEET_POSE = {"x_mm": 455.0, "y_mm": 5.0, "yaw_deg": 2.0}
MODEL_SHEET_BAD = [
    ("sheet a word", _set("sheet", "on the table"), "sheet"),
    ("sheet x nan", _set("sheet", SHEET_POSE | {"x_mm": nan}), "sheet.x_mm"),
    ("sheet without its yaw", _set("sheet", {"x_mm": 455.0, "y_mm": 5.0}), "sheet"),
    ("sheet yaw 1e9", _set("sheet", SHEET_POSE | {"yaw_deg": 1e9}), "sheet.yaw_deg"),
    ("sheet_std without a sheet", _set("sheet_std", SHEET_POSE), "sheet_std"),
]  # fmt: skip
for cid, edit, field in MODEL_SHEET_BAD:
    case(f"export: model {cid}", _argv("export"), _yaml("model.yaml", edit), f"model.yaml, field '{field}'")
VALIDATE_SHM = ["validate", "{d}/shm.yaml"] + VALIDATE_SHEET[2:]  # the model solved on shs (sheet ~455 5 2)
case("validate: --sheet-pose 5 m from where the model found the sheet (metres for mm, a slip)",
     VALIDATE_SHM + ["--sheet-pose", "5455", "5", "2"], None, "--sheet-pose 5455 5 2", "silent")  # fmt: skip
STD_NEGATIVE = _yaml("model.yaml", _set("sheet", SHEET_POSE), _set("sheet_std", SHEET_POSE | {"y_mm": -1.0}))
case("export: model sheet_std negative", _argv("export"), STD_NEGATIVE, "model.yaml, field 'sheet_std.y_mm'")
case("spots --model: a model's sheet_std negative", ["spots", "{d}/val/photos/0000.png", "--layout",
     "{d}/sheet/layout.yaml", "--model", "{d}/model.yaml"], STD_NEGATIVE, "sheet_std.y_mm")  # fmt: skip

# issue 46: the MuJoCo world, an empty session, a model's configurations
MUJOCO_CAPTURE = ["capture", "--layout", "{d}/sheet/layout.yaml", "--backend", "mujoco", "--per-point", "3"]
case("capture --backend mujoco without --world", MUJOCO_CAPTURE + ["-o", "{o}"], None, "--world")
case("capture --world a torn MJCF", MUJOCO_CAPTURE + ["--world", "{d}/w.xml", "-o", "{o}"],
     _touch("w.xml", "<mujoco><worldbody><body name='a'>"), "w.xml")  # fmt: skip
case("capture --world on --backend fake", FAKE_CAPTURE + ["--world", "{d}/layout.yaml", "-o", "{o}"], None,
     "--world")  # fmt: skip
case("mujoco-scene: no sheet.pdf beside the layout", _argv("mujoco-scene"), None, "sheet.pdf")
case("mujoco-scene --spring after joint 9", _argv("mujoco-scene") + ["--spring", "9:1e-4"], None, "--spring")
case("mujoco-scene --spring without a value", _argv("mujoco-scene") + ["--spring", "2"], None, "--spring")
case("mujoco-scene --friction with no passive joint", _argv("mujoco-scene") + ["--friction", "2:0.5"], None,
     "--friction")  # fmt: skip
case("mujoco-scene -o the layout's folder", ["mujoco-scene", "--layout", "{d}/sheet/layout.yaml", "-o",
     "{d}/sheet", "--force"], None, "-o")  # fmt: skip
case("new-session --aim without --camera", _argv("new-session") + ["--aim", "anywhere"], None, "--aim")
case("new-session --aim anywhere on a layout no sheet printed", ["new-session", "--layout", "{d}/layout.yaml",
     "--camera", "--aim", "anywhere", "-o", "{o}"], None, "layout.yaml")  # fmt: skip
case("new-session -o the layout's folder", ["new-session", "--layout", "{d}/sheet/layout.yaml", "-o",
     "{d}/sheet"], None, "-o")  # fmt: skip
case("configurations: a sheet layout, a model without a sheet pose", ["configurations", "panda", "--layout",
     "{d}/sheet/layout.yaml", "-o", "{o}"], None, "sheet")  # fmt: skip
case("configurations: no such point", _argv("configurations") + ["--point", "P9"], None, "P9")
case("configurations -o the model", ["configurations", "{d}/model.yaml", "--layout", "{d}/layout.yaml", "-o",
     "{d}/model.yaml", "--force"], None, "-o")  # fmt: skip


# --- 10. issue 47's sweep: corrupted copies of files lasercal wrote, where each used to pass or write ------
# a NaN in a field the command does not read is a corruption too (every YAML lasercal reads is checked whole)
UNREAD_NAN = [
    ("export", EXPORT + ["-o", "{o}"], "model.yaml", ("identification", "fit_rms_mm")),
    ("predict", PREDICT, "model.yaml", ("identification", "prior", "tolerances", "offset_mm")),
    ("solve", SOLVE + ["-o", "{o}"], "sess/session.yaml", ("simulated", "aim_noise_mm")),
    ("report", REPORT + ["-o", "{o}"], "val/validation.yaml", ("collector", "settings", "hold")),
    ("register", REGISTER + ["-o", "{o}"], "pmodel.yaml", ("identification", "sigma_mm")),
    ("capture", CAPTURE_SHEET, "sheet/layout.yaml", ("paper", "width_mm")),
    ("solve", ["solve", "{d}/shs", "--folds", "0", "-o", "{o}"], "shs/session.yaml",
     ("simulated", "sheet", "pose", "x_mm")),
]  # fmt: skip
for cmd, argv, rel, keys in UNREAD_NAN:
    field = ".".join(keys)
    case(f"{cmd}: {rel} NaN in {field}, a field it does not read", argv, _yaml(rel, _set(*keys, nan)),
         f"{rel.split('/')[-1]}, field '{field}'")  # fmt: skip
case("validate: a sheet layout's marker corner NaN", VALIDATE_SHM,
     _yaml("sheet/layout.yaml", lambda d: d["markers"]["ids"][0][0].__setitem__(0, nan)),
     "layout.yaml, field 'markers.ids.0'")  # fmt: skip
case("report: validation.csv a logged angle NaN", REPORT + ["-o", "{o}"],
     _cell("val/validation.csv", 0, "q3", "nan"), "validation.csv, line 3, column 'q3'")  # fmt: skip
# a simulated sheet session's truth file spoiled: refused before the model is written (it was written, exit 2)
case("solve: a sheet session's truth.yaml cut short", ["solve", "{d}/shs", "--folds", "0", "-o", "{o}"],
     _torn("shs/truth.yaml"), "truth.yaml", "torn")  # fmt: skip


# a pose session's session.yaml is a whole file: cut at a line end, it says so (it was read as complete)
def _last_line_lost(rel: str):
    """A YAML file cut at the line end before its last line of content (and its end line '...', if any)."""

    def fn(d: Path):
        lines = [ln for ln in (d / rel).read_text().splitlines() if ln.strip() != "..."]
        (d / rel).write_text("\n".join(lines[:-1]) + "\n")

    return fn


case("solve: a pose session.yaml truncated at a line end", ["solve", "{d}/ps", "--folds", "0", "-o", "{o}"],
     _last_line_lost("ps/session.yaml"), "ps/session.yaml", "torn")  # fmt: skip
# --report into the session it reads (it wrote its plots there)
case("diagnose --report the input session folder", DIAGNOSE + ["--report", "{d}/sess"], None, "would replace",
     "output")  # fmt: skip


@pytest.fixture
def watchdog():
    """A hang becomes a failure after WATCHDOG_S seconds."""

    def fire(*_):
        raise TimeoutError(f"no answer within {WATCHDOG_S} s: the command hangs")

    old = signal.signal(signal.SIGALRM, fire)
    signal.alarm(WATCHDOG_S)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize(
    "argv, setup, needle", [c[2:] for c in CASES], ids=[f"{c[0]}: {c[1]}" for c in CASES]
)
def test_bad_input_exits_2_with_one_line(argv, setup, needle, base, tmp_path, capsys, monkeypatch, watchdog):
    if ("{d}/mukca" in " ".join(argv) or "{d}/pt" in " ".join(argv)) and not (base / "mukca").is_dir():
        pytest.skip("the MUKCa data (../shared/data/mukca) is not here")
    d = tmp_path / "w"
    _work_copy(base, d)
    if setup is not None:
        setup(d)
    monkeypatch.chdir(d)
    monkeypatch.setattr("sys.stdin", open("/dev/null"))  # no terminal: nothing may wait for a person
    out = d / "out"
    args = [a.replace("{d}", str(d)).replace("{o}", str(out)) for a in argv]
    before = _snapshot(d)
    rc = main(args)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("\r")]
    assert rc == 2, f"exit {rc}; stderr {err[-500:]!r}"
    assert "Traceback" not in err
    # argparse's own errors name the command (lasercal capture: error: argument --hold: ...)
    assert len(lines) == 1 and re.match(r"lasercal( [\w-]+)?: error: ", lines[0]), err
    assert needle.lower() in lines[0].lower(), f"{needle!r} not named in {lines[0]!r}"
    assert not out.exists(), "an output was written"
    assert _snapshot(d) == before, "an existing file changed"


# --- 7. every numeric option of every command declares its range once (options.number) ----------------
def declared_numbers():
    """(command, option, its Range, nargs) of every numeric option."""
    for c in COMMANDS:
        for a in _subparser(c.name)._actions:
            rng = getattr(a.type, "range", None)
            if rng is not None and a.option_strings:
                yield c.name, a.option_strings[-1], rng, a.nargs


def _bad_values(rng) -> list:
    """NaN, infinities, text, and a value just past each bound."""
    vals = ["nan", "inf", "-inf", "1e400", "ten"]
    if rng.lo is not None:
        vals.append(repr(float(rng.lo)) if rng.lo_open else repr(rng.lo - max(1.0, abs(rng.lo))))
    if rng.hi is not None:
        vals.append(repr(float(rng.hi)) if rng.hi_open else repr(rng.hi + max(1.0, abs(rng.hi))))
    if rng.integer:
        vals.append(repr((rng.lo or 0) + 0.5))
    return vals


NUMERIC = [(cmd, opt, v, nargs) for cmd, opt, rng, nargs in declared_numbers() for v in _bad_values(rng)]


def test_no_option_is_a_bare_float_or_int():
    """A numeric option declared with type=float (or int) would take NaN, inf or a negative silently."""
    bare = [
        (c.name, a.option_strings or a.dest)
        for c in COMMANDS
        for a in _subparser(c.name)._actions
        if a.type in (float, int)
    ]
    assert not bare


def test_every_numeric_range_is_bounded():
    """No 'absurd magnitude' passes: each numeric option has a finite lower and upper bound."""
    unbounded = [(cmd, opt) for cmd, opt, rng, _ in declared_numbers() if rng.lo is None or rng.hi is None]
    assert not unbounded
    assert len({cmd for cmd, *_ in declared_numbers()}) >= 14  # all but export and import-mukca


OPTIONS = sorted({(cmd, opt, nargs) for cmd, opt, _, nargs in NUMERIC}, key=str)


@pytest.mark.parametrize("cmd, opt, nargs", OPTIONS, ids=[f"culprit: {c} {o}" for c, o, _ in OPTIONS])
def test_every_numeric_option_refuses_bad_values(cmd, opt, nargs, base, tmp_path, capsys):
    """Parsed before anything runs: exit 2, one line naming the option, nothing written; for each of
    NaN, +-inf, an overflow, text and a value just past each bound (one pytest item per option, the
    values in a loop: 500 items would cost more in set-up than in running)."""
    k = nargs if isinstance(nargs, int) else 1
    rng = next(r for c, o, r, _ in declared_numbers() if (c, o) == (cmd, opt))
    ok = repr(float(min(max(0.0, rng.lo), rng.hi)))
    if "{d}/mukca" in " ".join(_argv(cmd)) and not (base / "mukca").is_dir():
        pytest.skip("the MUKCa data (../shared/data/mukca) is not here")
    argv = [a.replace("{d}", str(base)).replace("{o}", str(tmp_path / "out")) for a in _argv(cmd)]
    for value in [v for c, o, v, _ in NUMERIC if (c, o) == (cmd, opt)]:
        rc = main(argv + [opt, value] + [ok] * (k - 1))
        err = capsys.readouterr().err
        assert (
            rc == 2 and len(err.splitlines()) == 1 and err.startswith(f"lasercal {cmd}: error: argument")
        ), err
        assert opt in err, err
    assert not (tmp_path / "out").exists()


# --- 8. plausible but suspicious: a warning that names it, the work done -------------------------------
def _dup_row(rel: str, row: int):
    def fn(d: Path):
        lines = (d / rel).read_text().splitlines()
        (d / rel).write_text("\n".join(lines + [lines[1 + row]]) + "\n")

    return fn


def _only_point(rel: str, name: str):
    """Keep the captures at one point of a session's captures.csv."""

    def fn(d: Path):
        lines = (d / rel).read_text().splitlines()
        (d / rel).write_text(
            "\n".join(lines[:1] + [ln for ln in lines[1:] if ln.startswith(name + ",")]) + "\n"
        )

    return fn


def _limits_rounded(rel: str, j: int, excess: float):
    """model.yaml's upper limit of joint j (0-based) rounded to ``excess`` rad below the largest angle
    measured in ``rel`` (a CSV with a q<j+1> column)."""

    def fn(d: Path):
        lines = (d / rel).read_text().splitlines()
        col = lines[0].split(",").index(f"q{j + 1}")
        q = max(float(ln.split(",")[col]) for ln in lines[1:])
        _edit_yaml(d / "model.yaml", lambda m: m["joints"][j].__setitem__("limits", [
            m["joints"][j]["limits"][0], q - excess]))  # fmt: skip

    return fn


WARNINGS = [
    ("solve", SOLVE + ["-o", "{o}"], "a capture saved twice", _dup_row("sess/captures.csv", 4), "line(s) 38"),
    ("diagnose", DIAGNOSE, "a capture saved twice", _dup_row("sess/captures.csv", 0), "captures.csv"),
    ("predict", PREDICT + ["--plane-z", "900"], "a plane above the aperture", None, "--plane-z"),
    ("predict", PREDICT, "a measured angle a hair beyond a rounded limit",
     _limits_rounded("configs.csv", 3, 0.003), "q4"),
    ("spots", ["spots", "{d}/val/photos/0000.png", "--layout", "{d}/layout.yaml"], "a layout without markers",
     None, "layout.yaml"),
    ("solve", SOLVE + ["--robot", "{d}/model.yaml", "-o", "{o}"], "measured angles a hair beyond a limit",
     _limits_rounded("sess/captures.csv", 5, 0.002), "q6"),
    ("plan", PLAN, "a capture saved twice", _dup_row("sess/captures.csv", 7), "captures.csv"),
    ("correct", _argv("correct"), "a last line with no line end (an editor's, or cut inside a number)",
     lambda d: (d / "goals.csv").write_text(GOALS.rstrip("\n")), "goals.csv, line 3"),
    ("report", REPORT + ["-o", "{o}"], "a capture saved twice", _dup_row("sess/captures.csv", 30),
     "captures.csv"),
    ("solve", ["solve", "{d}/pos", "--folds", "0", "-o", "{o}"], "a position capture saved twice",
     _dup_row("pos/captures.csv", 2), "captures.csv"),
    # an option given where it does nothing is named, not dropped in silence
    ("simulate", SIMULATE + ["--noise", "0.5", "-o", "{o}"], "a position option on a laser session", None,
     "--noise 0.5: ignored"),
    ("simulate", SIM_POS + [str(URDF), "--configs", "4", "--layout", "{d}/layout.yaml"],
     "a layout for a position session", None, "--layout"),
    ("spots", BASE["spots"] + ["--imagej-box", "32"], "an imagej option without --method imagej", None,
     "--imagej-box 32: ignored"),
    ("fullpose", FULLPOSE + ["--seed", "3", "-o", "{o}"], "--seed without --folds", None,
     "--seed 3: ignored"),
    ("solve", SOLVE + ["--payload", "1,0,0,100", "-o", "{o}"], "--payload without --extend", None,
     "--payload 1.0 0.0 0.0 100.0: ignored"),
    # beside issue 26 (section 9)
    ("sheet", SHEET + ["--place", "450", "0", "1.5708"], "a yaw in radians", None, "YAW 1.5708 deg: 90 deg"),
    ("sheet", SHEET + ["--tip-link", "tool0"], "--tip-link without --robot", None,
     "--tip-link tool0: ignored"),
    ("simulate", SIM_SHEET + ["--sheet-pose", "450", "0", "0.7854", "-o", "{o}"],
     "a --sheet-pose yaw in radians", None, "45 deg written in radians"),
    ("simulate", SIM_POS + [str(URDF), "--configs", "4", "--sheet-pose", "5", "5", "2"],
     "--sheet-pose on a position session", None, "--sheet-pose 5.0 5.0 2.0: ignored"),
    ("simulate", SIM_SHEET + ["-o", "{o}"], "a sheet layout's yaw in radians",
     _sheet_yaml("layout", "sheet", "yaw_deg", 0.5236), "field 'sheet.yaw_deg'"),
    ("export", EXPORT + ["--robot-id", "fr3", "-o", "{o}"], "--robot-id without --format franka", None,
     "--robot-id fr3: ignored"),
    ("export", EXPORT + ["--format", "franka", "-o", "{o}"], "what kinematics.yaml cannot carry", None,
     "not in kinematics.yaml: the laser"),
    ("export", EXPORT + ["--format", "franka", "--robot-id", "fr3", "-o", "{o}"],
     "a Panda written for an FR3", None, "--robot-id fr3: the model"),
    ("correct", _argv("correct"), "a rotation vector longer than pi",
     _touch("goals.csv", "x,y,z,rx,ry,rz\n400,0,500,4.0,0,0\n"), "goals.csv, line 2, column 'rx'"),
    ("solve", SOLVE + ["--prior", "{d}/prior.yaml", "-o", "{o}"], "a prior tolerance in metres",
     _touch("prior.yaml", "format: lasercal-prior/1\nprior: {point_offset_mm: 0.003}\n"),
     "field 'prior.point_offset_mm'"),
    ("diagnose", DIAGNOSE + ["--prior", "{d}/prior.yaml"], "a prior angle in degrees",
     _touch("prior.yaml", "format: lasercal-prior/1\nprior: {eccentricity_rad: 5.0}\n"),
     "field 'prior.eccentricity_rad'"),
    # issue 47 (item 15): on stderr, not on stdout
    ("validate", VALIDATE_SHM + ["--sheet-pose", "480", "5", "2"], "a --sheet-pose 25 mm from where the "
     "model found the sheet", None, "--sheet-pose 480 5 2: lays P6"),
    ("solve", SOLVE + ["-o", "{o}"], "every capture at one point", _only_point("sess/captures.csv", "P1"),
     "every capture is at one point, P1"),
]  # fmt: skip


@pytest.mark.parametrize("argv, setup, needle", [w[1:2] + w[3:] for w in WARNINGS],
                         ids=[f"warning: {w[0]}: {w[2]}" for w in WARNINGS])  # fmt: skip
def test_suspicious_input_warns_and_goes_on(argv, setup, needle, base, tmp_path, capsys, monkeypatch,
                                            watchdog):  # fmt: skip
    d = tmp_path / "w"
    _work_copy(base, d)
    if setup is not None:
        setup(d)
    monkeypatch.chdir(d)
    args = [a.replace("{d}", str(d)).replace("{o}", str(d / "out")) for a in argv]
    rc = main(args)
    err = capsys.readouterr().err
    warned = [ln for ln in err.splitlines() if ln.startswith("lasercal: warning: ")]
    assert rc == 0 and "Traceback" not in err and "error" not in err, err
    assert warned and any(needle in ln for ln in warned), err
    assert "{o}" not in " ".join(argv) or (d / "out").exists()


def test_a_measured_angle_a_hair_beyond_a_limit_is_kept(base, tmp_path, capsys):
    """A FANUC's J4 at -360.000 deg against a URDF limit of -6.28 rad: kept with a warning, and the
    prediction is the one at the measured angle; 0.2 rad beyond (a column or unit mistake) is refused."""
    d = tmp_path / "w"
    _work_copy(base, d)
    _limits_rounded("configs.csv", 3, 0.003)(d)
    assert main(["predict", str(d / "model.yaml"), str(d / "configs.csv")]) == 0
    kept = capsys.readouterr().out
    _limits_rounded("configs.csv", 3, 0.0)(d)  # the limit exactly at the angle: no warning, same spot
    assert main(["predict", str(d / "model.yaml"), str(d / "configs.csv")]) == 0
    out = capsys.readouterr()
    assert out.out == kept and "warning" not in out.err
    _limits_rounded("configs.csv", 3, 0.2)(d)
    assert main(["predict", str(d / "model.yaml"), str(d / "configs.csv")]) == 2
    err = capsys.readouterr().err
    # the row named is the first beyond the limit, and the tolerance shown the row's own: both depend on
    # the simulated poses
    assert "configs.csv, line " in err and "column 'q4'" in err and "is outside its limits [" in err


def test_an_output_named_like_its_command_is_replaced_with_force(tmp_path, monkeypatch, capsys):
    """'export panda -o export --force' replaces ./export: the command's name is no input path."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "export").write_text("old\n")
    rc = main(["export", "panda", "--format", "yaml", "-o", "export", "--force"])
    assert rc == 0, capsys.readouterr().err
    assert "lasercal-robot/1" in (tmp_path / "export").read_text()


# files saved with a byte-order mark, as UTF-16 (Windows 'Unicode') or with CRLF line ends are read
ENCODED_OK = [
    ("solve", SOLVE + ["-o", "{o}"], "sess/captures.csv"),
    ("solve", SOLVE + ["-o", "{o}"], "sess/session.yaml"),
    ("predict", PREDICT, "configs.csv"),
    ("export", EXPORT + ["-o", "{o}"], "model.yaml"),
    ("simulate", SIMULATE + ["-o", "{o}"], "layout.yaml"),
    ("spots", ["spots", "{d}/val/photos/0000.png", "--layout", "{d}/layout.yaml"], "layout.yaml"),
    ("correct", _argv("correct"), "goals.csv"),
    ("solve", SOLVE + ["--prior", "{d}/prior.yaml", "-o", "{o}"], "prior.yaml"),
]


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16", "crlf"])
@pytest.mark.parametrize("argv, rel", [e[1:] for e in ENCODED_OK],
                         ids=[f"{e[0]}: {e[2]}" for e in ENCODED_OK])  # fmt: skip
def test_bom_utf16_and_crlf_files_are_read(argv, rel, encoding, base, tmp_path, capsys):
    d = tmp_path / "w"
    _work_copy(base, d)
    text = (d / rel).read_text()
    if encoding == "crlf":
        (d / rel).write_bytes(text.replace("\n", "\r\n").encode())
    else:
        (d / rel).write_bytes(text.encode(encoding))
    args = [a.replace("{d}", str(d)).replace("{o}", str(d / "out")) for a in argv]
    assert main(args) == 0, capsys.readouterr().err
    assert "error" not in capsys.readouterr().err


def test_at_least_150_cases_cover_every_command():
    from lasercal.collector.cli.main import COMMANDS

    assert len(CASES) >= 150
    named = {c[2][0] for c in CASES}
    missing = {c.name for c in COMMANDS} - named
    assert not missing, missing


def test_every_command_has_cases_in_the_categories_it_can_fail():
    counts = case_counts()
    for c in COMMANDS:
        assert counts.get((c.name, "culprit")), c.name
        if declared_outputs(c.name):
            assert counts.get((c.name, "output")), c.name
    for name in INPUT_FILES:
        assert counts.get((name, "traceback")), name


def case_counts() -> dict:
    """(command, category) -> number of cases in this module (parametrised tests included)."""
    counts: dict = {}
    rows = [(c[2][0], c[0]) for c in CASES] + [(cmd, "culprit") for cmd, *_ in NUMERIC]
    rows += [(w[0], "warning") for w in WARNINGS]
    rows += [(e[0], "traceback") for e in ENCODED_OK for _ in range(3)]
    for key in rows:
        counts[key] = counts.get(key, 0) + 1
    return counts


if __name__ == "__main__":  # the table of cases per command and category (python tests/test_bad_inputs.py)
    counts = case_counts()
    print(f"{'command':18}" + "".join(f"{c:>11}" for c in CATEGORIES) + f"{'total':>8}")
    for c in COMMANDS:
        row = [counts.get((c.name, k), 0) for k in CATEGORIES]
        print(f"{c.name:18}" + "".join(f"{n:>11}" for n in row) + f"{sum(row):>8}")
    col = [sum(counts.get((c.name, k), 0) for c in COMMANDS) for k in CATEGORIES]
    print(f"{'all':18}" + "".join(f"{n:>11}" for n in col) + f"{sum(col):>8}")
