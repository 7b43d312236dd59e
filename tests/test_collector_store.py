"""The crash-safe session store: durable appends, torn-line recovery, discards, validation on resume."""

from __future__ import annotations

import os

import numpy as np
import pytest

from lasercal.collector.errors import SessionError
from lasercal.collector.sessions.store import CaptureStore, CsvLog
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.session import load_layout, load_session, session_meta

LAYOUT = load_layout(builtin_dir("layouts") / "thesis.yaml")


def _rows(k: int, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    q = np.array([0.1, -0.5, 0.2, -2.0, 0.1, 1.8, 0.6])
    return [
        {
            "point": ["P1", "P2", "P3"][i % 3],
            "t": 10.0 * (i + 1) + rng.random(),
            "q": q + rng.normal(0, 0.3, 7),
            "dq": rng.normal(0, 1e-3, 7),
            "tau": rng.normal(0, 10, 7),
            "robot_mode": "Guiding",
        }
        for i in range(k)
    ]


def _new(tmp_path, name="s"):
    return CaptureStore.create(tmp_path / name, session_meta("panda", LAYOUT, 825.0), 7, ["robot_mode"])


def test_appended_rows_read_back_exactly_and_each_is_fsynced(tmp_path, monkeypatch):
    synced = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real(fd)))
    store = _new(tmp_path)
    before = len(synced)
    rows = _rows(5)
    for r in rows:
        store.append(r)
    assert len(synced) - before == 5  # one fsync per capture, before append returns
    store.close()
    s = load_session(tmp_path / "s")
    assert list(s.point) == [r["point"] for r in rows]
    np.testing.assert_array_equal(s.q, [r["q"] for r in rows])  # full precision: bit-exact round trip
    np.testing.assert_array_equal(s.tau, [r["tau"] for r in rows])
    assert list(s.extra["robot_mode"]) == ["Guiding"] * 5


def test_resume_cuts_a_torn_last_line_and_keeps_every_complete_row(tmp_path):
    store = _new(tmp_path)
    for r in _rows(4):
        store.append(r)
    store.close()
    path = tmp_path / "s" / "captures.csv"
    intact = path.read_bytes()
    with open(path, "ab") as f:
        f.write(b"P2,51.3,0.12,-0.4")  # a kill in the middle of a write
    store = CaptureStore.open(tmp_path / "s")
    assert store.recovered == len(b"P2,51.3,0.12,-0.4")
    assert path.read_bytes() == intact
    assert store.point == ["P1", "P2", "P3", "P1"]
    store.append(_rows(5)[4])
    store.close()
    assert load_session(tmp_path / "s").m == 5


def test_discard_removes_exactly_the_last_row_durably(tmp_path):
    store = _new(tmp_path)
    rows = _rows(3)
    for r in rows[:2]:
        store.append(r)
    kept = (tmp_path / "s" / "captures.csv").read_bytes()
    store.append(rows[2])
    assert store.discard_last() == "P3"
    assert (tmp_path / "s" / "captures.csv").read_bytes() == kept
    assert store.discard_last() == "P2"
    assert store.discard_last() == "P1"
    assert store.discard_last() is None  # the header stays
    store.close()
    assert load_session(tmp_path / "s").m == 0


def test_a_session_folder_is_never_overwritten(tmp_path):
    _new(tmp_path).close()
    with pytest.raises(SessionError, match="--resume"):
        _new(tmp_path)


def test_resume_recreates_the_header_when_killed_before_it(tmp_path):
    _new(tmp_path).close()
    (tmp_path / "s" / "captures.csv").unlink()
    store = CaptureStore.open(tmp_path / "s")
    store.append(_rows(1)[0])
    store.close()
    assert load_session(tmp_path / "s").m == 1


def test_resume_rejects_a_corrupted_row_naming_its_line(tmp_path):
    store = _new(tmp_path)
    for r in _rows(3):
        store.append(r)
    store.close()
    path = tmp_path / "s" / "captures.csv"
    lines = path.read_text().splitlines(keepends=True)
    lines[2] = lines[2].replace(lines[2].split(",")[3], "oops", 1)
    path.write_text("".join(lines))
    with pytest.raises(FormatError, match=r"captures.csv, line 3, column 'q2'"):
        CaptureStore.open(tmp_path / "s")


def test_resume_of_a_folder_without_session_yaml_is_an_error(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SessionError, match="no session.yaml"):
        CaptureStore.open(tmp_path / "empty")


def test_csv_log_writes_comment_header_and_durable_rows(tmp_path):
    log = CsvLog(tmp_path / "v.csv", ["index", "q1", "photo"], ["units: rad"])
    log.append({"index": "0", "q1": 0.1, "photo": "photos/0000.png"})
    log.close()
    assert (tmp_path / "v.csv").read_text() == "# units: rad\nindex,q1,photo\n0,0.1,photos/0000.png\n"
    with pytest.raises(SessionError, match="exists"):
        CsvLog(tmp_path / "v.csv", ["index"])


def test_a_torn_captures_csv_is_refused_saying_that_resume_repairs_it(tmp_path):
    """Read as it is (solve, plan, ...), a captures.csv whose last row a kill tore is refused naming the file
    and the line, and the message says what mends it: ``capture --resume`` (which does, above)."""
    meta = session_meta("panda", LAYOUT, 825.0, collector={"per_point": 2})  # as capture writes it
    store = CaptureStore.create(tmp_path / "capture", meta, 7, ["robot_mode"])
    for r in _rows(4):
        store.append(r)
    store.close()
    path = tmp_path / "capture" / "captures.csv"
    with open(path, "ab") as f:
        f.write(b"P2,51.3,0.12,-0.4")
    with pytest.raises(FormatError) as e:
        load_session(tmp_path / "capture")
    assert e.value.line == 6 and e.value.path == str(path)
    assert f"`lasercal capture --resume {tmp_path / 'capture'}` cuts the torn row off" in str(e.value)


def test_a_torn_session_yaml_is_refused_whatever_it_lost(tmp_path):
    """session.yaml written by lasercal says where it ends (solver/whole.py): cut at any line end it is
    refused, though what is left parses; a session.yaml without that claim (written by hand, or before)
    that lost ``frame: sheet`` is refused by its own points, off the plane, or by captures at points its
    ``requested`` no longer lists."""
    store = _new(tmp_path)
    for r in _rows(3):
        store.append(r)
    store.close()
    ypath = tmp_path / "s" / "session.yaml"
    whole = ypath.read_text()
    lines = whole.splitlines(keepends=True)
    assert lines[0].startswith("# whole file") and lines[-1] == "...\n"
    for k in range(2, len(lines)):
        ypath.write_text("".join(lines[:k]))
        with pytest.raises(FormatError, match="cut short") as e:
            load_session(tmp_path / "s")
        assert e.value.path == str(ypath)
    ypath.write_text(whole)
    assert load_session(tmp_path / "s").m == 3
    old = "".join(lines[1:-1])  # the same file as written before it said where it ends
    ypath.write_text(old[: old.index("- P2")])  # cut inside requested: P2 and P3 are captured
    with pytest.raises(FormatError, match="'requested' \\(P1\\) does not list"):
        load_session(tmp_path / "s")
