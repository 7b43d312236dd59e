"""The live frames of the view: the session's camera read between its photos, what is found drawn on it.

A thread reads the camera at up to ``fps`` frames a second (through :class:`SharedCamera`, so that a
frame never interleaves with the session's own photo), finds the sheet's markers (ArUco, at half
resolution), the laser spot (``vision.detect`` around the reddest pixel) and, through the markers'
homography, where the spot lies on the sheet and whether it is inside the target's circle; it draws them,
encodes the frame as JPEG and hands it to the page. The numbers a set-up needs come with each frame:
markers read, the sheet's scale (mm per pixel) and share of the frame, clipped pixels, focus.

The live analysis is a view, not a measurement: the capture's spot is measured on its full photo by the
session (``sessions.spotcam``), with the lens calibration this skips.
"""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np

HALF = 0.5  # the frame the page gets, and the one the markers are found on: half the camera's resolution
WINDOW_PX = 48  # half-side of the full-resolution window around the reddest pixel the spot detector reads
SIM_RENDERS = 3.0  # a simulated camera's new pictures a second at most
MARKERS_EVERY_S = 0.5  # the markers are found again this often (the sheet and camera stay put)
MAX_MM_PER_PX = 0.5  # a spot ~2 mm across wants 0.3-0.5 mm/px (docs/sessions.md, "Where to put a camera")
CLIP_LEVEL = 250  # a channel at or above this is clipped (8-bit)
JPEG_QUALITY = 80


class SharedCamera:
    """A camera that the session's photos and the view's frames share, one read at a time.

    ``frame()`` is the camera's own when it has one (a read that changes nothing the session's photos
    depend on, e.g. the validation's fake camera, whose photos' noise counts photos), else ``photo()``.
    Every other attribute is the camera's.
    """

    def __init__(self, camera):
        self._camera = camera
        self._lock = threading.Lock()

    def photo(self) -> np.ndarray:
        with self._lock:
            return self._camera.photo()

    def frame(self) -> np.ndarray:
        with self._lock:
            grab = getattr(self._camera, "frame", None) or self._camera.photo
            return grab()

    def __getattr__(self, name):
        return getattr(self._camera, name)


class LiveFeed:
    """Frames for the view, with what is found drawn on them.

    Parameters
    ----------
    camera : SharedCamera
    state : SessionState, whose ``target`` the frames are checked against and whose ``frame_info`` they fill
    markers : vision.plane.MarkerLayout or None, the sheet's markers (layout frame, mm)
    outline : (k, 2) array or None, the sheet's edge in the layout's frame, mm (None: the markers' hull)
    fps : float, frames a second at most
    scene : callable() -> hashable, or None: what the picture depends on, for a simulated camera (the fake
        arm's true pose): an unchanged scene is not rendered again (its picture would be the same, up to
        noise; rendering one takes 0.15-0.4 s), its frame is analysed and sent as a new one would be
    """

    def __init__(self, camera, state, markers=None, outline=None, fps: float = 8.0, scene=None):
        self.camera, self.state, self.markers, self.fps = camera, state, markers, fps
        self.outline, self.scene = outline, scene
        self._last: tuple = (None, None)  # the scene and the picture taken of it
        self._rendered = -1e9  # when it was taken (monotonic s)
        self._drawn: tuple = (None, None)  # the target and the annotated frame of the last picture
        self._found: tuple = (-1e9, None, 0, [])  # when the markers were last found, their homography, ...
        self._cond = threading.Condition()
        self.seq, self.jpeg, self.t = 0, b"", 0.0
        self._times: list[float] = []
        self._focus_best = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True, name="live-feed")
        if markers is not None:
            aruco = cv2.aruco
            d = aruco.getPredefinedDictionary(getattr(aruco, markers.dictionary))
            self._detector = aruco.ArucoDetector(d, aruco.DetectorParameters())
        self.error = ""

    def start(self) -> LiveFeed:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def _loop(self) -> None:
        period = 1.0 / self.fps
        while not self._stop.is_set():
            t0 = time.monotonic()
            try:
                img, fresh = self.grab()
                grabbed = time.time()
                target = self.state.data.get("target")
                if fresh or target != self._drawn[0] or self._drawn[1] is None:
                    self._drawn = (target, self.annotate(img))
                jpeg, info = self._drawn[1]
            except Exception as e:  # a camera that fails a frame: said on the page, the session goes on
                self.error = f"live frame: {e}"
                self.state.set_frame_info({"error": self.error})
                self._stop.wait(1.0)
                continue
            self.publish(jpeg, info, grabbed)
            self._stop.wait(max(period - (time.monotonic() - t0), 0.0))

    def grab(self) -> tuple[np.ndarray, bool]:
        """The camera's next frame, and whether it is a new picture. A simulated scene is rendered again
        only when it changed, and at most :data:`SIM_RENDERS` times a second (a render costs 0.1-0.4 s of
        the CPU the simulated session runs on); meanwhile its last picture is the frame."""
        if self.scene is None:
            return self.camera.frame(), True
        key, now = self.scene(), time.monotonic()
        if key != self._last[0] and now - self._rendered >= 1.0 / SIM_RENDERS:
            self._last, self._rendered = (key, self.camera.frame()), now
            return self._last[1], True
        return self._last[1], False

    def publish(self, jpeg: bytes, info: dict, grabbed: float) -> None:
        """Hand a frame to the page's waiting readers."""
        now = time.monotonic()
        self._times = [t for t in self._times if now - t < 2.0] + [now]
        fps = (
            (len(self._times) - 1) / max(self._times[-1] - self._times[0], 1e-9)
            if len(self._times) > 1
            else 0
        )
        with self._cond:
            self.seq += 1
            self.jpeg, self.t = jpeg, grabbed
            self.state.set_frame_info({**info, "seq": self.seq, "t": grabbed, "fps": round(fps, 1)})
            self._cond.notify_all()

    def wait(self, after: int, timeout: float) -> tuple[int, bytes, float]:
        """The first frame after ``after`` (waits up to ``timeout`` s): its number, JPEG and grab time."""
        end = time.monotonic() + timeout
        with self._cond:
            while self.seq <= after and time.monotonic() < end:
                self._cond.wait(max(end - time.monotonic(), 0.0))
            return self.seq, self.jpeg, self.t

    # ------------------------------------------------------------------ what a frame shows
    def annotate(self, img: np.ndarray) -> tuple[bytes, dict]:
        """The frame, half size, with the markers, the sheet's outline, the target and the spot drawn; and
        what was found (JSON-able)."""
        small = cv2.resize(img, None, fx=HALF, fy=HALF, interpolation=cv2.INTER_AREA)
        spot = find_spot(img, small)  # before anything is drawn on the half frame
        gray = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
        h, w = img.shape[:2]
        info: dict = {"size": [w, h]}
        H = self._markers(gray, small, info)
        # a pixel with any channel clipped: every byte thresholded, then the channels summed (OpenCV; numpy's
        # max over the channel axis is 50 times slower at this size)
        hot = cv2.threshold(img, CLIP_LEVEL - 1, 255, cv2.THRESH_BINARY)[1]
        info["clipped_px"] = int(cv2.countNonZero(cv2.cvtColor(hot, cv2.COLOR_BGR2GRAY)))
        focus = float(cv2.Laplacian(gray, cv2.CV_32F).var())
        self._focus_best = max(self._focus_best, focus)
        info.update(focus=round(focus, 1), focus_rel=round(focus / max(self._focus_best, 1e-9), 3))
        target = self.state.data.get("target")
        info["spot_px"] = None if spot is None else [round(float(v), 1) for v in spot]
        if H is not None:
            self._on_sheet(H, small, spot, target, info)
        if spot is not None:
            u, v = (np.asarray(spot) * HALF).astype(int)
            cv2.drawMarker(small, (int(u), int(v)), (255, 0, 255), cv2.MARKER_CROSS, 18, 2)
        setup = []
        if self.markers is not None:
            n, k = len(self.markers.corners), info.get("markers_read", 0)
            setup.append(f"markers: {k} of {n} read" + ("" if k == n else " -- every marker must be in view"))
            if info.get("mm_per_px") is not None:
                mpp = info["mm_per_px"]
                near = (
                    "" if mpp <= MAX_MM_PER_PX else f" -- move the camera closer (<= {MAX_MM_PER_PX} mm/px)"
                )
                setup.append(f"sheet: {mpp:.2f} mm/px, {info['fill'] * 100:.0f} % of the frame{near}")
        setup.append(
            f"clipped: {info['clipped_px']} px" + (" -- lower the exposure" if info["clipped_px"] else "")
        )
        setup.append(f"focus: {focus:.0f} ({info['focus_rel'] * 100:.0f} % of the sharpest seen)")
        info["setup"] = setup
        n_markers = len(self.markers.corners) if self.markers is not None else 0
        info["setup_ok"] = bool(
            self.markers is not None
            and info.get("markers_read") == n_markers
            and (info.get("mm_per_px") or 99) <= MAX_MM_PER_PX
        )
        ok, jpeg = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        return jpeg.tobytes(), info

    def _markers(self, gray: np.ndarray, small: np.ndarray, info: dict):
        """Find the markers, draw them; the homography sheet mm -> full-resolution px, or None."""
        if self.markers is None:
            return None
        now = time.monotonic()
        if now - self._found[0] < MARKERS_EVERY_S:  # found a moment ago: drawn again, not searched
            _, H, read, found = self._found
            info.update(
                markers_read=read, markers_missing=sorted(set(self.markers.corners) - {i for i, _ in found})
            )
            for _, c in found:
                cv2.polylines(small, [c.astype(np.int32)], True, (0, 200, 0), 2)
            return H
        corners, ids, _ = self._detector.detectMarkers(gray)
        known = self.markers.corners
        found = (
            []
            if ids is None
            else [(int(i), c.reshape(4, 2)) for i, c in zip(ids.ravel(), corners) if int(i) in known]
        )
        info["markers_read"] = len(found)
        info["markers_missing"] = sorted(set(known) - {i for i, _ in found})
        for _, c in found:
            cv2.polylines(small, [c.astype(np.int32)], True, (0, 200, 0), 2)
        H = None
        if len(found) >= 2:  # 8 corners at least for a stable homography
            mm = np.vstack([np.asarray(known[i], dtype=float) for i, _ in found])
            H, _ = cv2.findHomography(mm, np.vstack([c for _, c in found]) / HALF)
        self._found = (now, H, len(found), found)
        return H

    def _on_sheet(self, H: np.ndarray, small: np.ndarray, spot, target, info: dict) -> None:
        """The sheet's outline and scale, the target's circle and where the spot lies on the sheet."""
        outline = self.outline
        if outline is None:
            pts = np.vstack([np.asarray(c, dtype=float) for c in self.markers.corners.values()])
            outline = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
        px = cv2.perspectiveTransform(np.asarray(outline, np.float64)[None], H)[0]
        cv2.polylines(small, [(px * HALF).astype(np.int32)], True, (255, 160, 0), 2)
        h, w = info["size"][1], info["size"][0]
        info["fill"] = round(float(abs(cv2.contourArea(px.astype(np.float32))) / (w * h)), 3)
        centre = np.asarray(outline, dtype=float).mean(axis=0)
        a, b = cv2.perspectiveTransform(np.array([[centre, centre + [10.0, 0.0]]]), H)[0]
        info["mm_per_px"] = round(10.0 / float(np.hypot(*(b - a))), 3)
        Hinv = np.linalg.inv(H)
        xy = None
        if spot is not None:
            xy = cv2.perspectiveTransform(np.asarray(spot, np.float64)[None, None], Hinv)[0, 0]
            info["spot_mm"] = [round(float(v), 2) for v in xy]
        if target:
            t = np.asarray(target["xy"], dtype=float)
            c, e = cv2.perspectiveTransform(np.array([[t, t + [target["tol_mm"], 0.0]]]), H)[0]
            inside = None if xy is None else bool(np.hypot(*(xy - t)) <= target["tol_mm"])
            info["inside"], info["off_mm"] = (
                inside,
                None if xy is None else round(float(np.hypot(*(xy - t))), 1),
            )
            colour = (0, 200, 0) if inside else (0, 140, 255)
            r = max(int(np.hypot(*(e - c)) * HALF), 3)
            cv2.circle(small, tuple(int(v) for v in c * HALF), r, colour, 2)


def find_spot(img: np.ndarray, half: np.ndarray | None = None):
    """The laser spot of a live frame, (u, v) px at full resolution, or None: the reddest (or greenest)
    pixel of the frame at a quarter of its size, then the centroid of the laser colour's excess over half
    its peak in a window around it at full resolution (a view's estimate, ~0.3 px; a capture's spot is
    measured on its photo by ``vision``'s detector). ``half``: the frame at half size, if made already
    (nothing drawn on it yet)."""
    half = cv2.resize(img, None, fx=HALF, fy=HALF, interpolation=cv2.INTER_AREA) if half is None else half
    q = cv2.resize(half, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA).astype(np.int16)
    b, g, r = q[..., 0], q[..., 1], q[..., 2]
    colour = np.maximum(r - np.maximum(g, b), g - np.maximum(r, b))
    v, u = np.unravel_index(int(np.argmax(colour)), colour.shape)
    if colour[v, u] < 12:  # nothing coloured stands out: no spot in view
        return None
    u0, v0 = max(int(u * 4) - WINDOW_PX, 0), max(int(v * 4) - WINDOW_PX, 0)
    w = img[v0 : v0 + 2 * WINDOW_PX, u0 : u0 + 2 * WINDOW_PX].astype(np.float32)
    wb, wg, wr = w[..., 0], w[..., 1], w[..., 2]
    excess = np.maximum(wr - np.maximum(wg, wb), wg - np.maximum(wr, wb))
    excess = np.maximum(excess - 0.5 * excess.max(), 0)
    m = cv2.moments(excess)
    if m["m00"] <= 0:
        return None
    return u0 + m["m10"] / m["m00"], v0 + m["m01"] / m["m00"]
