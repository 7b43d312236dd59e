"""What the commands say to the operator (issue 53, item 4): argparse's errors name the command; options
that would change nothing are refused (exit 2, one line naming the option, nothing written); the messages
the issue found wrong; the disk a session will need, said before its first photo."""

from __future__ import annotations

import re

import pytest

from lasercal.collector.cli.main import main


def _err(argv, capsys) -> tuple[int, list[str], str]:
    code = main(argv)
    got = capsys.readouterr()
    return code, got.err.strip().splitlines(), got.out


def test_argparse_errors_name_the_command(tmp_path, capsys):
    code, err, _ = _err(
        ["validate", "panda", "--layout", "thesis", "--auto", "-o", str(tmp_path / "v")], capsys
    )
    said = "unrecognized arguments: --auto (lasercal validate --help lists its options)"
    assert code == 2 and err == [f"lasercal validate: error: {said}"]
    code, err, _ = _err(["capture", "--layout", "thesis", "--hold", "x"], capsys)
    assert code == 2 and len(err) == 1 and err[0].startswith("lasercal capture: error: argument --hold: 'x'")
    assert not (tmp_path / "v").exists()


@pytest.mark.parametrize(
    "extra, named",
    [
        (
            ["--photos", "none", "--photo-format", "jpg"],
            "--photos none --photo-format jpg: no photo is taken",
        ),
        (["--photos", "first"], "--photos first: no photo is taken without a camera"),
        (
            ["--camera", "fake", "--photos", "none", "--photo-format", "jpg"],
            "--photo-format jpg: --photos none",
        ),
    ],
)
def test_photo_options_that_change_nothing_are_refused(sheet, tmp_path, capsys, extra, named):
    out = tmp_path / "s"
    argv = [
        "capture",
        "--layout",
        str(sheet),
        "--backend",
        "fake",
        "--auto",
        "--per-point",
        "1",
        "-o",
        str(out),
    ]
    code, err, _ = _err(argv + extra, capsys)
    assert code == 2 and len(err) == 1 and named in err[0], err
    assert not out.exists()


def test_validate_refuses_a_format_for_no_photos(tmp_path, capsys):
    out = tmp_path / "v"
    argv = ["validate", "panda", "--layout", "thesis", "-n", "2", "--backend", "fake", "-o", str(out)]
    code, err, _ = _err(argv + ["--photos", "none", "--photo-format", "png"], capsys)
    assert code == 2 and len(err) == 1 and "--photo-format png: --photos none keeps no photo" in err[0]
    assert not out.exists()


def test_the_messages_the_issue_found(sheet, tmp_path, capsys):
    # --point given: the message does not ask for it, it names one that works
    code, err, _ = _err(["configurations", "panda", "--layout", str(sheet), "--point", "P1", "-o",
                         str(tmp_path / "c.csv")], capsys)  # fmt: skip
    assert code == 2 and len(err) == 1 and "pass --point" not in err[0]
    assert "validation point P1 is calibration point P1" in err[0] and re.search(
        r"e\.g\. --point P\d", err[0]
    )
    code, err, _ = _err(["mujoco-scene", "--layout", "thesis", "-o", str(tmp_path / "m")], capsys)
    assert code == 2 and len(err) == 1 and "this layout is not a printed sheet" in err[0]
    for value in ("nan", "inf", "1.5"):
        code, err, _ = _err(["demo", "--seed", value, "-o", str(tmp_path / "d")], capsys)
        said = (
            f"argument --seed: '{value}' is not a whole number (expected a whole number in [0, 4294967295])"
        )
        assert code == 2 and err == [f"lasercal demo: error: {said}"]
    assert not any((tmp_path / p).exists() for p in ("c.csv", "m", "d"))


def _help(cmd: str, capsys) -> str:
    with pytest.raises(SystemExit):
        main([cmd, "--help"])
    return " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("cmd", ["report", "demo", "diagnose"])
def test_seed_has_help(cmd, capsys):
    text = _help(cmd, capsys)
    assert re.search(r"--seed S \w", text), text


def test_capture_help_says_auto_drives_fake_and_mujoco(capsys):
    text = _help("capture", capsys)
    auto = text[text.index("--auto the") :][:200]
    assert "fake" in auto and "MuJoCo" in auto, auto


def test_photo_words_and_the_start_estimate():
    from lasercal.collector.sessions.photos import PhotoPolicy, start_estimate_line

    assert PhotoPolicy("none", "png").words() == "none: each photo is measured, then dropped"
    assert PhotoPolicy("first", "jpg").words() == "first, JPG"
    assert start_estimate_line(PhotoPolicy("none"), 45, 5) is None
    assert start_estimate_line(PhotoPolicy("all", "png"), 45, 5).startswith(
        "this session will write about 65.2 MB: 45 photos"
    )
    assert "0.8 MB: 5 photos" in start_estimate_line(PhotoPolicy("first", "jpg"), 45, 5)


def test_validate_says_the_disk_it_will_need_before_its_first_photo(tmp_path, capsys):
    argv = [
        "validate",
        "panda",
        "--layout",
        "thesis",
        "-n",
        "2",
        "--backend",
        "fake",
        "-o",
        str(tmp_path / "v"),
    ]
    code, _, out = _err(argv, capsys)
    assert code == 0
    need = out.index("this session will write about 2.9 MB: 2 photos")
    assert need < out.index("photo 1/2")
