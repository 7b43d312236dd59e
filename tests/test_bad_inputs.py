"""Bad input, every command: exit 2, one line naming the file or option, no traceback, nothing written.

Each case runs ``main([...])`` in-process on copies of small valid inputs (a simulated
session, its identified model, a validation run, circle-point measurements, a MUKCa robot
folder) with one thing wrong, and checks: exit code 2; stderr is exactly one line
``lasercal: error: ...`` that names the file or option at fault; no traceback; the output
path was not created; no file in the working folder changed (bytes and mtime). A watchdog
turns a hang into a failure.
"""

from __future__ import annotations

import hashlib
import re
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main

MUKCA = Path(__file__).resolve().parents[2] / "shared" / "data" / "mukca"
URDF = Path(__file__).resolve().parent / "data" / "ur5.urdf"
WATCHDOG_S = 30


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Valid inputs, made once: sess/, model.yaml, layout.yaml, configs.csv, val/, fp.csv, mukca/, and pos/
    (a position session of the UR5 URDF, which it names as 'robot: arm.urdf' beside its captures)."""
    d = tmp_path_factory.mktemp("valid")
    layout = yaml.safe_load((Path(__file__).resolve().parents[1] / "data/layouts/thesis.yaml").read_text())
    (d / "layout.yaml").write_text(yaml.safe_dump(layout))
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
    return d


def _snapshot(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): (p.stat().st_mtime_ns, hashlib.sha1(p.read_bytes()).hexdigest())
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


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
PLAN = ["plan", "{d}/sess", "--next", "2"]
STUDY = ["study-mukca", "{d}/mukca", "--robots", "panda_1", "--quick"]

# (id, argv, setup, needle in the message); "{o}" is the output path (must not appear), "{d}" the folder
CASES: list[tuple] = []


def case(cid, argv, setup=None, needle=None):
    CASES.append((cid, argv, setup, needle))


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
    "solve": (SOLVE + ["-o", "{o}"], {"--folds": ["-1", "1", "nan"]}),
    "report": (REPORT + ["-o", "{o}"], {"--bootstrap": ["-1", "nan"], "--refits": ["-1"], "--seed": ["-1"]}),
    "diagnose": (DIAGNOSE + ["--report", "{o}"], {
        "--alpha": ["0", "1", "-0.1", "nan"],
        "--bootstrap": ["-1"],
        "--refits": ["-1"],
        "--payload": ["1,2", "-1,0,0,0", "nan,0,0,0", "a,b,c,d"],
    }),
    "predict": (PREDICT, {"--plane-z": ["nan", "inf"]}),
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
            case(f"{cmd} {opt} {v}", argv + [opt, v], None, opt.lstrip("-").split("-")[0])

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

# --- 2. output paths: checked before any work, nothing kept is replaced ------------------------------
WRITERS = {
    "simulate": (SIMULATE, "folder"),
    "solve": (SOLVE, "file"),
    "export": (EXPORT, "file"),
    "fullpose": (FULLPOSE, "file"),
    "simulate-fullpose": (SIMFP, "file"),
    "report": (REPORT, "folder"),
    "import-mukca": (IMPORT, "folder"),
    "study-mukca": (STUDY, "folder"),
    "validate": (VALIDATE, "folder"),
    "capture": (FAKE_CAPTURE, "folder"),
}
for cmd, (argv, kind) in WRITERS.items():
    case(f"{cmd} -o in a missing folder", argv + ["-o", "{d}/no/such/dir/out"], None, "-o")
    if kind == "file":
        case(f"{cmd} -o existing file", argv + ["-o", "{d}/kept.out"], _touch("kept.out"), "--force")
        case(f"{cmd} -o a folder", argv + ["-o", "{d}/adir"], _mkdir("adir"), "-o")
    else:
        case(f"{cmd} -o existing folder", argv + ["-o", "{d}/kept"], _mkdir("kept"), "kept")
        case(f"{cmd} -o a file", argv + ["-o", "{d}/afile"], _touch("afile"), "-o")

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
    "model link mass negative": _yaml("model.yaml", _set("links", [{"mass": -1.0, "com": [0, 0, 0]}] * 7)),
    "model home outside limits": _yaml("model.yaml", _set("home", [10.0] * 7)),
    "model units m": _yaml("model.yaml", _set("units", {"length": "m", "angle": "rad"})),
}
for cid, setup in MODEL_BAD.items():
    case(f"export: {cid}", EXPORT + ["-o", "{o}"], setup, "model.yaml")
for cid in (
    "model not utf-8",
    "model limits in degrees",
    "model aperture in metres",
    "model extension nan",
):
    case(f"predict: {cid}", PREDICT, MODEL_BAD[cid], "model.yaml")
    case(f"validate: {cid}", VALIDATE + ["-o", "{o}"], MODEL_BAD[cid], "model.yaml")

SESSION_BAD = {
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
for opt, values in {"--margin": ["-1", "nan", "1"], "--restarts": ["-1", "1.5"], "--tcp": ["nan"]}.items():
    for v in values:
        case(f"correct {opt} {v}", CORRECT + [opt] + ([v, "0", "0"] if opt == "--tcp" else [v]), None, opt)
case("correct: program in degrees", CORRECT, _degrees("configs.csv", Q), "configs.csv")
case("correct: program value nan", CORRECT, _cell("configs.csv", 0, "q2", "nan"), "configs.csv")
case("correct: unknown tool", CORRECT + ["--tool", "T9"], None, "--tool")
case(
    "correct: no nominal",
    CORRECT,
    _yaml("model.yaml", _set("name", "mybot"), lambda m: m.pop("nominal"), lambda m: m.pop("identification")),
    "nominal",
)


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


@pytest.mark.parametrize("argv, setup, needle", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_exits_2_with_one_line(argv, setup, needle, base, tmp_path, capsys, monkeypatch, watchdog):
    if "{d}/mukca" in " ".join(argv) and not (base / "mukca").is_dir():
        pytest.skip("the MUKCa data (../shared/data/mukca) is not here")
    d = tmp_path / "w"
    shutil.copytree(base, d)
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
    assert len(lines) == 1 and lines[0].startswith("lasercal: error: "), err
    assert needle.lower() in lines[0].lower(), f"{needle!r} not named in {lines[0]!r}"
    assert not out.exists(), "an output was written"
    assert _snapshot(d) == before, "an existing file changed"


def test_at_least_150_cases_cover_every_command():
    from lasercal.collector.cli.main import COMMANDS

    assert len(CASES) >= 150
    named = {c[1][0] for c in CASES}
    missing = {c.name for c in COMMANDS} - named
    assert not missing, missing
