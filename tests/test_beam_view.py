"""``beam-check --device``: the photos of a joint-7 turn taken live (Enter at each angle, q when done),
kept in a folder and measured as given photos; with ``--view`` the page shows the frames and the count."""

from __future__ import annotations

import io
import json
import re
import threading
import time
import urllib.request

import cv2
import numpy as np
import pytest

from lasercal.collector.cli.main import main
from lasercal.vision.render import LaserSpot, Photo, look_down, render

CENTRE, RADIUS = np.array([400.0, 300.0]), 60.0  # px: the circle the spot runs on as joint 7 turns
ANGLES = np.radians([0, 50, 100, 150, 200])


def _photo(k: int) -> np.ndarray:
    view = look_down(size=(800, 600), mm_per_px=0.2, centre=(0.0, 0.0), height=800.0, z=0.0)
    u, v = CENTRE + RADIUS * np.array([np.cos(ANGLES[k]), np.sin(ANGLES[k])])
    return render(Photo(view, (), (LaserSpot(u, v, 2.5, 0.8, 0.2),)), seed=k)


def test_beam_check_takes_its_photos_live_and_fits_the_circle(tmp_path, monkeypatch, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(len(ANGLES)):  # the device gives 4 frames per photo: 3 dropped (stale buffers), 1 read
        for j in range(4):
            cv2.imwrite(str(frames / f"{4 * k + j:04d}.png"), _photo(k))
    monkeypatch.setattr("sys.stdin", io.StringIO("\n" * len(ANGLES) + "q\n"))  # Enter at each angle, q
    rc = main(
        ["beam-check", "--device", str(frames / "%04d.png"), "--save", str(tmp_path / "beam"), "--json"]
    )
    assert rc == 0
    out = capsys.readouterr().out
    res = json.loads(out[out.index("{") :])
    assert len(res["images"]) == len(ANGLES) and sorted(p.name for p in (tmp_path / "beam").iterdir()) == [
        f"beam_{k:02d}.png" for k in range(1, len(ANGLES) + 1)
    ]
    assert abs(res["radius_px"] - RADIUS) < 0.2 and np.allclose(res["centre_px"], CENTRE, atol=0.2)


class Turning:
    """A camera on a joint-7 turn: each photo the next angle's, a live frame the present one's."""

    name = "turning"

    def __init__(self):
        self.k = 0

    def photo(self):
        img = _photo(self.k)
        self.k += 1
        return img

    def frame(self):
        return _photo(min(self.k, len(ANGLES) - 1))

    def close(self):
        """Nothing to release."""


@pytest.mark.skipif(
    __import__("importlib").util.find_spec("aiohttp") is None, reason="the live view needs aiohttp"
)
def test_the_beam_checks_live_view_shows_the_spot_and_the_photos_taken(tmp_path):
    from lasercal.collector.hardware.triggers import EnterTrigger
    from lasercal.collector.sessions.beamphotos import take_beam_photos
    from lasercal.collector.view import ViewOptions

    said = io.StringIO()
    asked = threading.Event()
    states = []

    def press() -> str:  # the operator at the keyboard, reading the page before each press
        while "live view: " not in said.getvalue():
            time.sleep(0.05)
        url = re.search(r"live view: (http://\S+)", said.getvalue()).group(1).replace("/?", "/state?")
        end = time.monotonic() + 60
        while time.monotonic() < end:
            s = json.loads(urllib.request.urlopen(url, timeout=10).read())
            if s["phase"] == "aiming" and s["frame"].get("spot_px"):
                states.append(s)
                break
            time.sleep(0.1)
        asked.set()
        return "" if len(states) <= 3 else "q"

    photos = take_beam_photos(
        Turning(), tmp_path / "beam", EnterTrigger(press), ViewOptions(port=0), None, said
    )
    assert len(photos) == 3 and asked.is_set()
    first = states[0]
    assert first["kind"] == "beam-check" and first["progress"] == [{"name": "photos", "done": 0, "want": 3}]
    u, v = first["frame"]["spot_px"]
    assert np.hypot(u - 400 - RADIUS, v - 300) < 1.0  # the live spot where the first angle puts it
    assert states[-1]["progress"][0]["done"] == 3 and states[-1]["last"]["number"] == 3
