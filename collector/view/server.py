"""The live view's web server: one page, the session's state as server-sent events, the frames, three
actions.

Served by aiohttp (the ``view`` extra) in a thread of the session's process, on its own event loop: an
asyncio server holds a page's two long-lived streams (the state's events and the frame poll) without a
thread each, its ``StreamResponse`` is server-sent events as they are, and ``AppRunner`` starts and stops
the server from the session's side in a few lines. The page (``page.html``) is one file of HTML and
JavaScript, no build step.

Routes (every one but the page needs the run's token: ``?token=`` or the ``X-Token`` header; a request
without it, or with another or a malformed one, is refused with 403):

- ``GET /`` the page (without the token: the same file, which holds no state of the run and asks for the
  token); ``GET /state`` the state as JSON; ``GET /events`` the state as server-sent events, one ``data:``
  line per change;
- ``GET /frame?after=N`` the first live frame after frame N (JPEG; headers ``X-Frame-Seq`` and
  ``X-Frame-Time``, the time the camera gave it, s since the epoch), waiting up to 2 s (then 204);
- ``GET /problem.jpg`` the photo that showed what went wrong;
- ``POST /action`` ``{"do": "capture" | "discard" | "stop"}``: queued for the session, which takes it at
  its next safe point (409 with the reason when it does not take it now; a stop is taken in every phase).
  Nothing here moves the arm: after the page's capture or discard the next move waits for the terminal.

The server binds to 127.0.0.1 unless ``--view-host`` says otherwise; the token is printed in the
address(es), once, and the page keeps it for the run. Served on all addresses (``0.0.0.0``, ``::``), the
links printed are the machine's own interface addresses (:func:`local_addresses`), which another device
on the same network can open.
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import secrets
import socket
import threading
from importlib import resources

from lasercal.collector.errors import DeviceError, MissingExtraError

LOOPBACK = ("127.0.0.1", "localhost", "::1")
ANY = ("0.0.0.0", "::", "")  # every address of the machine
PROBE = ("10.255.255.254", 9)  # a UDP socket 'connected' here (no packet is sent) says the outgoing address


def _fib_trie_addresses() -> list[str]:
    """Linux: the machine's own IPv4 addresses (the kernel's 'host LOCAL' routes), read from /proc."""
    try:
        lines = open("/proc/net/fib_trie").read().splitlines()
    except OSError:
        return []
    found, leaf = [], ""
    for line in lines:
        text = line.strip()
        if text.startswith("|--"):
            leaf = text[3:].strip()
        elif text.startswith("/32 host LOCAL") and leaf and leaf not in found:
            found.append(leaf)
    return found


def local_addresses(family: int = socket.AF_INET) -> list[str]:
    """The machine's non-loopback addresses another device on its networks can open, from the standard
    library and the kernel only: the host name's addresses, the kernel's local routes (Linux) and the
    address a UDP socket would send from (``connect`` on UDP sends nothing). Sorted, without duplicates;
    empty when the machine has none.
    """
    found: list[str] = []
    try:
        found += [a[4][0] for a in socket.getaddrinfo(socket.gethostname(), None, family)]
    except OSError:
        pass
    if family == socket.AF_INET:
        found += _fib_trie_addresses()
        try:
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
                probe.connect(PROBE)
                found.append(probe.getsockname()[0])
        except OSError:
            pass
    keep = []
    for a in found:
        try:
            ip = ipaddress.ip_address(a.split("%")[0])
        except ValueError:
            continue
        if not (ip.is_loopback or ip.is_unspecified or ip.is_multicast) and a not in keep:
            keep.append(a)
    return sorted(keep, key=lambda a: ipaddress.ip_address(a.split("%")[0]))


def _token_bytes(given) -> bytes:
    """A token as bytes, whatever it holds (non-ASCII, or a header's undecodable bytes): compared, never
    failing."""
    return str(given).encode("utf-8", "surrogateescape")


def aiohttp_web():
    """aiohttp's server module, or a one-line error with the pip command when the extra is missing."""
    try:
        from aiohttp import web
    except ImportError:
        raise MissingExtraError("the live view (--view)", "aiohttp", "view") from None
    return web


class ViewServer:
    """The page and its streams, served from a thread until :meth:`stop`.

    Parameters
    ----------
    state : SessionState
    feed : LiveFeed or None (no camera: the page shows the state only)
    host : str, the address to bind (127.0.0.1 unless the operator asked for another)
    port : int, 0 for any free port
    """

    def __init__(self, state, feed=None, host: str = "127.0.0.1", port: int = 8765):
        self.web = aiohttp_web()
        self.state, self.feed, self.host, self.port = state, feed, host, port
        self.token = secrets.token_urlsafe(12)
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._serve, daemon=True, name="view-server")

    @property
    def remote(self) -> bool:
        return self.host not in LOOPBACK

    def url(self, with_token: bool = True, host: str | None = None) -> str:
        host = self.host if host is None else host
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{self.port}/" + (f"?token={self.token}" if with_token else "")

    def urls(self) -> list[str]:
        """The links, with the token, another device opens: the bound address, or when it is every address
        of the machine (``0.0.0.0``, ``::``) each of its non-loopback addresses (none: loopback's)."""
        if self.host not in ANY:
            return [self.url()]
        family = socket.AF_INET6 if self.host == "::" else socket.AF_INET
        found = local_addresses(family)
        if family == socket.AF_INET6:  # '::' takes IPv4 too on most systems
            found = local_addresses(socket.AF_INET) + found
        return [self.url(host=a) for a in found] or [self.url(host="127.0.0.1")]

    def start(self) -> ViewServer:
        """Start serving; returns once the port is bound (raises DeviceError when it cannot be)."""
        self._thread.start()
        self._ready.wait(30)
        if self._error is not None:
            raise DeviceError(f"--view: cannot serve on {self.host}:{self.port} ({self._error})")
        return self

    def stop(self) -> None:
        """Stop serving: the page's streams end (it shows the last state); nothing is left behind."""
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=10)

    # ------------------------------------------------------------------ the server's thread
    def _serve(self) -> None:
        web = self.web
        asyncio.set_event_loop(self._loop)

        @web.middleware
        async def guard(request, handler):
            return await self._guard(request, handler)

        app = web.Application(middlewares=[guard])
        app.add_routes(
            [
                web.get("/", self._page),
                web.get("/state", self._state),
                web.get("/events", self._events),
                web.get("/frame", self._frame),
                web.get("/problem.jpg", self._problem),
                web.post("/action", self._action),
            ]
        )
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=1.0)
        try:
            self._loop.run_until_complete(runner.setup())
            site = web.TCPSite(runner, self.host, self.port, reuse_address=True)
            self._loop.run_until_complete(site.start())
            self.port = runner.addresses[0][1]
        except Exception as e:  # a port taken, an address not of this machine: said by start()
            self._error = e
            self._ready.set()
            return
        self._ready.set()
        try:
            self._loop.run_forever()
        finally:
            self._loop.run_until_complete(runner.cleanup())
            self._loop.close()

    async def _guard(self, request, handler):
        """Every request needs the run's token; on loopback, a Host header of this machine (a page of
        another site that resolves its name to 127.0.0.1 gets nothing)."""
        host = request.host.rsplit(":", 1)[0].strip("[]")
        if not self.remote and host not in LOOPBACK:
            return self.web.json_response({"error": f"host {host} is not this machine"}, status=403)
        try:
            given = request.query.get("token") or request.headers.get("X-Token") or ""
        except (UnicodeError, ValueError):  # a query that does not decode
            given = ""
        if not secrets.compare_digest(_token_bytes(given), _token_bytes(self.token)):
            if request.method == "GET" and request.path == "/":  # the page alone: it asks for the token
                return await self._page(request)
            return self.web.json_response(
                {"error": "a token is required: open the address lasercal printed, with its ?token="},
                status=403,
            )
        return await handler(request)

    async def _page(self, request):
        html = resources.files("lasercal.collector.view").joinpath("page.html").read_text()
        return self.web.Response(text=html, content_type="text/html", headers={"Cache-Control": "no-store"})

    async def _state(self, request):
        return self.web.json_response(self.state.snapshot())

    async def _events(self, request):
        resp = self.web.StreamResponse(
            headers={
                "Content-Type": "text/event-stream",
                "Cache-Control": "no-store",
                "X-Accel-Buffering": "no",
            }
        )
        await resp.prepare(request)
        loop, seq = asyncio.get_running_loop(), -1
        try:
            while True:  # on every change, and twice a second for the live frame's numbers
                seq = await loop.run_in_executor(None, self.state.wait_change, seq, 0.5)
                await resp.write(f"data: {json.dumps(self.state.snapshot())}\n\n".encode())
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        return resp

    async def _frame(self, request):
        if self.feed is None:
            return self.web.Response(status=204)
        try:
            after = int(request.query.get("after", "0"))
        except ValueError:
            return self.web.json_response({"error": "after: a frame number"}, status=400)
        loop = asyncio.get_running_loop()
        seq, jpeg, t = await loop.run_in_executor(None, self.feed.wait, after, 2.0)
        if seq <= after or not jpeg:
            return self.web.Response(status=204)
        headers = {"X-Frame-Seq": str(seq), "X-Frame-Time": f"{t:.6f}", "Cache-Control": "no-store"}
        return self.web.Response(body=jpeg, content_type="image/jpeg", headers=headers)

    async def _problem(self, request):
        jpeg = self.state.problem_jpeg
        if jpeg is None:
            return self.web.Response(status=204)
        return self.web.Response(body=jpeg, content_type="image/jpeg", headers={"Cache-Control": "no-store"})

    async def _action(self, request):
        try:
            action = str((await request.json()).get("do", ""))
        except (ValueError, AttributeError):
            return self.web.json_response(
                {"error": 'expected JSON {"do": "capture|discard|stop"}'}, status=400
            )
        refused = self.state.post(action)
        if refused:
            return self.web.json_response({"error": refused}, status=409)
        return self.web.json_response({"ok": True, "queued": action})
