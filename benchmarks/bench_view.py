"""What the live view costs a session, and what it shows: frame rate and photo-to-page latency.

A hands-free camera session (sheet at 450 0 0, ``capture --backend fake --camera fake --guide move --auto
--per-point 9``: 45 captures) runs without the view, then with ``--view`` and headless Chromium (Debian's,
through Playwright) showing the page the whole time; the two sessions' captures.csv must be the same
bytes (the view reads, it changes nothing). Printed: each session's wall and CPU time (the process's, all
threads), the frames the page showed per second of session, their latency from the camera's frame to the
page's ``img.onload`` (median, 90 %), the live feed's own rate, and the view's work per frame on a
1280 x 960 photo (what bounds the rate with a real camera, whose frames cost nothing to grab). The fake
camera renders a frame in 0.1-0.4 s; a scene that has not moved is not rendered again.

Run: ``nice python benchmarks/bench_view.py [--per-point 9] [--repeat 1]`` (a few minutes a session; the
machine's load average is printed with the numbers: other jobs on the 2 cores slow both sessions).
"""

from __future__ import annotations

import argparse
import io
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path

import cv2
import numpy as np

from lasercal.collector.sessions.settings import capture_settings
from lasercal.collector.sessions.start import CaptureGuide, start_capture
from lasercal.collector.sessions.state import SessionState
from lasercal.collector.view import ViewOptions
from lasercal.collector.view.live import LiveFeed
from lasercal.vision.plane import load_markers
from lasercal.vision.sheet import design_sheet, write_layout

ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]  # fmt: skip


def session(sheet: Path, folder: Path, per_point: int, view: bool) -> dict:
    """One hands-free session; with ``view``, a headless Chromium page open on it throughout."""
    given = {"backend": "fake", "per_point": per_point, "camera": "fake", "aim_noise": 3.0, "seed": 0}
    started = start_capture(
        capture_settings(given, str(sheet), str(folder)), CaptureGuide(True, move=True, yes=True)
    )
    out = io.StringIO()
    stats: dict = {}
    if not view:
        t0, c0 = time.monotonic(), time.process_time()
        started.run(out)
        return {"wall": time.monotonic() - t0, "cpu": time.process_time() - c0}
    from playwright.sync_api import sync_playwright

    done = threading.Event()
    t0, c0 = time.monotonic(), time.process_time()
    runner = threading.Thread(target=lambda: (started.run(out, ViewOptions(port=0)), done.set()), daemon=True)
    runner.start()
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=shutil.which("chromium"), args=ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        while "live view: " not in out.getvalue():
            time.sleep(0.05)
        url = out.getvalue().split("live view: ", 1)[1].split()[0]
        page.goto(url)
        opened = time.monotonic()
        while not done.is_set():
            v = page.evaluate("({f: window.viewStats.frames, l: window.viewStats.latencies.slice()})")
            stats.update(frames=v["f"], latencies=v["l"])
            state = page.evaluate("window.viewStats.state && window.viewStats.state.frame.fps")
            stats.setdefault("feed_fps", []).append(state or 0)
            time.sleep(1.0)
        stats["shown_s"] = time.monotonic() - opened
        browser.close()
    runner.join()
    stats.update(wall=time.monotonic() - t0, cpu=time.process_time() - c0)
    return stats


class Webcam:
    """A camera whose frames cost nothing to read, as a webcam's (a photo of the session, given again)."""

    name = "webcam"

    def __init__(self, img: np.ndarray):
        self.img = img

    def photo(self) -> np.ndarray:
        return self.img.copy()

    def close(self) -> None:
        """Nothing to release."""


def pipeline(sheet: Path, folder: Path, seconds: float = 20.0) -> dict:
    """The view alone with a camera whose frames are free: frames shown per second and their latency."""
    from playwright.sync_api import sync_playwright

    from lasercal.collector.view import live_view

    state = SessionState("capture")
    state.update(target={"xy": [0.0, 0.0], "tol_mm": 5.0, "label": "P3"})
    cam = Webcam(cv2.imread(str(next((folder / "photos").glob("*.png")))))
    said = io.StringIO()
    state._out = said
    with live_view(state, ViewOptions(port=0, fps=30), cam, sheet), sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=shutil.which("chromium"), args=ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(said.getvalue().split("live view: ", 1)[1].split()[0])
        time.sleep(3.0)  # past the first frames
        f0 = page.evaluate("window.viewStats.frames")
        time.sleep(seconds)
        v = page.evaluate("({f: window.viewStats.frames, l: window.viewStats.latencies.slice()})")
        browser.close()
    n = v["f"] - f0
    return {"fps": n / seconds, "latencies": v["l"][-n:]}


def work_per_frame(sheet: Path, folder: Path) -> float:
    """The view's work on one 1280 x 960 photo (markers, spot, outline, target, JPEG), s: median of 20."""
    photo = cv2.imread(str(next((folder / "photos").glob("*.png"))))
    state = SessionState("capture")
    state.update(target={"xy": [0.0, 0.0], "tol_mm": 5.0, "label": "P3"})
    feed = LiveFeed(None, state, load_markers(sheet))
    times = []
    for _ in range(20):
        t = time.perf_counter()
        feed.annotate(photo)
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--per-point", type=int, default=9)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--frames-only", action="store_true", help="only the view's own cost (no sessions)")
    a = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_view_"))
    sheet = work / "layout.yaml"
    write_layout(sheet, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 0.0, "yaw_deg": 0.0})
    rows = []
    if a.frames_only:  # a short session for its photos
        session(sheet, work / "plain0", 1, False)
    for k in range(0 if a.frames_only else a.repeat):
        for view in (False, True):
            folder = work / f"{'view' if view else 'plain'}{k}"
            load = os.getloadavg()[0]
            r = session(sheet, folder, a.per_point, view)
            rows.append((view, r, load))
            same = (folder / "captures.csv").read_bytes() == (
                work / f"plain{k}" / "captures.csv"
            ).read_bytes()
            extra = ""
            if view:
                lat = np.array(r["latencies"])
                rate = r["frames"] / r["shown_s"]
                med, p90 = 1000 * np.median(lat), 1000 * np.quantile(lat, 0.9)
                extra = (
                    f"; page {r['frames']} frames in {r['shown_s']:.0f} s = {rate:.1f}/s, latency median "
                    f"{med:.0f} ms (90 %: {p90:.0f}), feed {np.median(r['feed_fps']):.1f} frames/s; "
                    f"captures.csv the same bytes: {same}"
                )
            print(
                f"{'with' if view else 'without'} view: {r['wall']:.1f} s wall, {r['cpu']:.1f} s CPU "
                f"(load average {load:.1f}){extra}",
                flush=True,
            )
    plain = [r for v, r, _ in rows if not v]
    viewed = [r for v, r, _ in rows if v]
    for what in ("wall", "cpu") if rows else ():
        ratio = np.mean([r[what] for r in viewed]) / np.mean([r[what] for r in plain])
        print(f"{what} time with the view / without: {ratio:.3f}")
    print(f"the view's work per 1280 x 960 frame: {1000 * work_per_frame(sheet, work / 'plain0'):.0f} ms")
    load = os.getloadavg()[0]
    r = pipeline(sheet, work / "plain0")
    lat = np.array(r["latencies"])
    print(
        f"the view with frames that cost nothing (a webcam's): {r['fps']:.1f} frames/s on the page, latency "
        f"median {1000 * np.median(lat):.0f} ms (90 %: {1000 * np.quantile(lat, 0.9):.0f}; load average "
        f"{load:.1f})"
    )
    print(f"(work folder {work})")


if __name__ == "__main__":
    main()
