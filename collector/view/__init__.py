"""The live view (``--view``) of ``capture``, ``validate`` and ``beam-check``: a page on the operator's
machine showing what the camera sees and what the session is doing (issue 48).

The session writes its state (:class:`~lasercal.collector.sessions.state.SessionState`); the live feed
(:mod:`.live`) reads the camera between the session's photos; the server (:mod:`.server`, aiohttp, the
``view`` extra, imported only with ``--view``) serves both to the page (``page.html``). :func:`live_view`
starts and stops them around a session: in the session's own process, so a killed session leaves nothing
behind (no file, no other process), and ``--resume`` brings the page back.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

DEFAULT_PORT = 8765


@dataclass(frozen=True)
class ViewOptions:
    """Where the view is served.

    Attributes
    ----------
    host : str, 127.0.0.1 unless ``--view-host`` names another address (another device then reaches it)
    port : int, 0 for any free port
    fps : float, live frames a second at most
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    fps: float = 8.0


def sheet_outline(layout_file) -> np.ndarray | None:
    """The printed page's edge in the sheet's frame (mm), from a layout ``lasercal sheet`` wrote, or None."""
    from lasercal.solver.formats.robots import load_yaml
    from lasercal.vision.sheet import page_to_sheet

    try:
        paper = (load_yaml(layout_file) or {}).get("paper") or {}
        w, h = float(paper["width_mm"]), float(paper["height_mm"])
    except (KeyError, TypeError, ValueError, OSError):
        return None
    return page_to_sheet([[0, 0], [w, 0], [w, h], [0, h]], w, h)


def simulated_scene(camera):
    """What a fake camera's picture depends on (:class:`~.live.LiveFeed`'s ``scene``): the fake arm's true
    pose and the exposure; None for any other camera (each frame is read)."""
    from lasercal.collector.hardware.fake import FakeRobot

    robot = getattr(camera, "robot", None)
    if not isinstance(robot, FakeRobot):
        return None
    return lambda: (robot.true_q().tobytes(), getattr(camera, "gain", 1.0))


def qr_lines(url: str) -> str:
    """The link as a QR code in the terminal, when the pure-Python ``segno`` or ``qrcode`` is installed;
    otherwise nothing (lasercal does not depend on either: the printed link is typed or copied)."""
    import io

    try:
        import segno
    except ImportError:
        segno = None
    out = io.StringIO()
    try:
        if segno is not None:
            segno.make(url, error="l").terminal(out=out, compact=True)
        else:
            import qrcode

            qr = qrcode.QRCode(border=1)
            qr.add_data(url)
            qr.print_ascii(out=out)
    except Exception:  # ImportError, or a library's own failure: the link alone
        return ""
    return out.getvalue()


@contextmanager
def live_view(state, options: ViewOptions, camera=None, layout_file=None):
    """Serve the view of a session while the ``with`` block runs it.

    Parameters
    ----------
    state : SessionState, the session's
    options : ViewOptions
    camera : the session's camera or None; when given the block must photograph through the yielded
        camera (a :class:`~.live.SharedCamera`), which the live frames share
    layout_file : the layout file, whose ``markers`` the frames are checked against (None: none)

    Yields
    ------
    the camera the session photographs with (the shared one), or None
    """
    from lasercal.collector.view.live import LiveFeed, SharedCamera
    from lasercal.collector.view.server import ViewServer

    server = ViewServer(state, None, options.host, options.port)  # refused before anything runs
    shared = feed = None
    if camera is not None:
        from lasercal.vision.plane import load_markers

        markers = load_markers(layout_file) if layout_file is not None else None
        shared = SharedCamera(camera)
        outline = sheet_outline(layout_file) if layout_file else None
        feed = LiveFeed(shared, state, markers, outline, options.fps, simulated_scene(camera))
        server.feed = feed
    server.start()
    if server.remote:
        urls = server.urls()
        state.say(
            f"live view: {urls[0]}   (served to other devices on {options.host}: open "
            f"{'it' if len(urls) == 1 else 'any of these'} on a phone or tablet on the same network)\n"
            + "".join(f"live view: {u}\n" for u in urls[1:])
            + qr_lines(urls[0])
        )
    else:
        state.say(f"live view: {server.url()}\n")
    if feed is not None:
        feed.start()
    try:
        yield shared
    finally:
        time.sleep(0.6)  # the page gets the session's last state before the server goes
        if feed is not None:
            feed.stop()
        server.stop()
