"""Issue 33's rough edges, each seen by a newcomer: help without defaults, a header naming the robot both
models share, a Robot printed as an address, API errors naming command-line options, a URDF comment naming
a file that does not exist, progress bars written into redirected output."""

from __future__ import annotations

import argparse
import importlib
import shutil
import time

import pytest

import lasercal
from lasercal.collector.cli.main import COMMANDS, build_parser, main
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.robots import resolve_robot_path


def _parser(name: str) -> argparse.ArgumentParser:
    p = build_parser(name)
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


@pytest.mark.parametrize("name", [c.name for c in COMMANDS])
def test_every_help_shows_the_defaults(name):
    """Every option with a default value says it in --help (argparse's own text for it, not a copy)."""
    p = _parser(name)
    for a in p._actions:
        d = a.default
        if not a.option_strings or d is None or d is False or d is argparse.SUPPRESS:
            continue
        entry = "".join(p._get_formatter()._format_action(a).split())  # the option's --help, unwrapped
        shown = "".join(map(str, d)) if isinstance(d, list | tuple) else str(d)
        said = "default" in (a.help or "")  # the help's own words, e.g. "(default 60)"
        assert said or f"(default:{shown})" in entry, (name, a.option_strings, entry)


def test_simulate_help_shows_per_point_aim_noise_and_seed():
    text = " ".join(_parser("simulate").format_help().split())
    for opt, default in (
        ("--per-point PER_POINT", "15"),
        ("--aim-noise AIM_NOISE", "1.0"),
        ("--seed SEED", "0"),
    ):
        assert f"(default: {default})" in text.split(opt, 2)[2][:200], opt


def test_a_robot_prints_as_what_it_is(tmp_path):
    assert repr(lasercal.load_model("panda")) == "<Robot panda: nominal, 7 joints, tools flange>"
    cal = tmp_path / "cal.yaml"
    shutil.copy(resolve_robot_path("panda_thesis_identified"), cal)
    r = repr(lasercal.load_model(cal))
    assert r == f"<Robot panda_thesis_identified: calibrated ({cal}), nominal panda, 7 joints, tools flange>"


def test_api_errors_name_python_arguments_and_the_cli_its_options(tmp_path, capsys):
    robot = lasercal.load_model("panda")
    with pytest.raises(FormatError, match=r"^tool: 'panda' has no tool 'T9'"):
        robot.tool("T9")
    with pytest.raises(FormatError, match=r"^tool: a TCP is 3 finite numbers"):
        robot.tool((0.0, 1.0))
    goals = tmp_path / "g.csv"
    goals.write_text("x,y,z\n450,0,300\n")
    assert main(["correct", "panda", str(goals), "-o", str(tmp_path / "o.csv"), "--tool", "T9"]) == 2
    assert "argument --tool: 'panda' has no tool 'T9'" in capsys.readouterr().err


def test_correct_names_the_calibrated_model_file(tmp_path):
    cal = tmp_path / "my_calibration.yaml"
    shutil.copy(resolve_robot_path("panda_thesis_identified"), cal)
    goals = tmp_path / "g.csv"
    goals.write_text("x,y,z\n450,0,300\n")
    assert main(["correct", str(cal), str(goals), "-o", str(tmp_path / "o.csv")]) == 0
    head = (tmp_path / "o.csv").read_text().splitlines()[0]
    assert head.startswith(f"# lasercal correct {cal} (panda_thesis_identified, nominal panda)")


def test_the_urdf_comment_names_a_module_that_exists():
    from lasercal.solver.formats.export import export
    from lasercal.solver.formats.robots import load_model

    text = export(load_model("panda_thesis_identified"), "urdf")
    module = text.split("(written by ", 1)[1].split(")", 1)[0]
    assert importlib.import_module(module).to_urdf  # the module that wrote it


def test_no_progress_bar_when_the_output_is_not_a_terminal(tmp_path, monkeypatch, capsys):
    """The demo's bar (tqdm, on stderr) stays out of a redirected stderr: pytest's is not a terminal."""
    import lasercal.collector.demo as demo

    def slow_demo(out, opts, progress):  # longer than the bar's delay, so that a bar would show
        for _ in range(3):
            time.sleep(0.3)
            progress("step")
        return {}

    monkeypatch.setattr(demo, "run_demo", slow_demo)
    monkeypatch.setattr(demo, "format_summary", lambda s: "done")
    assert main(["demo", "-o", str(tmp_path / "d")]) == 0
    out = capsys.readouterr()
    assert out.out == "done\n" and out.err == ""
