"""The README's recipe ("Your robot: print, tape, calibrate, use") runs exactly as printed on the simulated
robot, with the substitution its rehearsal sentence gives: ``--backend fake --camera fake`` in place of the
real backend and camera, ``--auto`` added to ``capture`` -- and fewer captures and configurations
(``--per-point 2``, ``-n 3``) to keep it short (about 35 s of CPU; ``--per-point 1`` would leave solve no
cross-validation, whose NaN validate refuses to read). Every line must exit 0: an option a
command does not take (``validate --auto`` once) fails the line, with the command's name in its message.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
REAL = "--backend franky --host 172.16.0.2 --camera 0"
FAKE = "--backend fake --camera fake"


def recipe() -> list[list[str]]:
    """The recipe's command lines (comments dropped), as argv lists without ``lasercal``."""
    text = README.read_text()
    block = re.search(r"## Your robot: print, tape, calibrate, use\n+```bash\n(.*?)```", text, re.S)
    assert block, "README.md has no recipe block"
    return [shlex.split(line.split("  #")[0])[1:] for line in block.group(1).splitlines() if line.strip()]


def rehearsed(argv: list[str]) -> list[str]:
    """A recipe line as the rehearsal sentence says: the fake backend and camera, --auto for capture; fewer
    captures and configurations."""
    line = " ".join(argv)
    if REAL in line:
        line = line.replace(REAL, FAKE + (" --auto" if argv[0] == "capture" else ""))
    line = line.replace("--per-point 9", "--per-point 2").replace("-n 60", "-n 3")
    return shlex.split(line)


def test_the_rehearsal_sentence_names_the_substitution():
    flat = " ".join(README.read_text().split())
    assert f"`{FAKE}` in place of `{REAL}`, and `--auto` added to `capture`" in flat
    lines = recipe()
    assert [a[0] for a in lines][:6] == ["sheet", "capture", "solve", "validate", "validate", "report"]
    assert sum(REAL in " ".join(a) for a in lines) == 3


def test_the_readme_recipe_runs_as_printed_on_the_simulated_robot(tmp_path, monkeypatch, capsys):
    from lasercal.collector.cli.main import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.stdin", open("/dev/null"))  # nothing may wait for a person
    (tmp_path / "goals.csv").write_text("x,y,z\n450,0,100\n500,50,150\n")  # the user's goals (docs/use.md)
    for argv in recipe():
        args = rehearsed(argv)
        code = main(args)
        err = capsys.readouterr().err
        assert code == 0, f"lasercal {' '.join(args)}: exit {code}: {err}"
    for out in ("session/captures.csv", "model.yaml", "val_nominal/validation.csv", "report/index.html",
                "panda_calibrated.urdf", "kinematics.yaml", "commands.csv"):  # fmt: skip
        assert (tmp_path / out).is_file(), out
