"""The photo phase of a camera session's capture: the photo taken, its spot measured and the photo kept as
the policy says (:func:`spot_cells`), and the run's photo step (:class:`PhotoStep`, a part of
:class:`~collector.sessions.capture.CaptureRun`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.collector.sessions.exposure import readable_by, settle_exposure
from lasercal.collector.sessions.photos import ALL_PNG, PhotoPolicy, estimate_line
from lasercal.collector.sessions.standstill import PHOTO_MOVED_MM, PHOTO_TRIES, moved_during_photo
from lasercal.solver.formats.captures import EYE_XYZ
from lasercal.solver.formats.session import session_layout

# a camera session's columns (docs/formats.md; an outside script's too); lasercal's own capture adds EYE_XYZ
SPOT_COLUMNS = ("photo", "camera_x", "camera_y", "camera_sx", "camera_sy", "camera_note")


@dataclass(frozen=True)
class Seen:
    """What the camera made of a capture (:func:`spot_cells`).

    Attributes
    ----------
    cells : dict, the row's :data:`SPOT_COLUMNS` (``photo`` empty when the photo was not kept)
    said : str, the line(s) said at once; without a final newline when the spot was not measured (the
        caller says what becomes of the capture)
    nbytes : int, the photo's size as encoded for its file, bytes (0 with ``--photos none``)
    img : (h, w, 3) uint8 array, the photo
    eye : (3,) array or None, where the camera stands, layout frame, mm (:class:`spotcam.SpotMeasure`)
    in_view : tuple of int, the markers the photo found (:class:`spotcam.SpotMeasure`)
    """

    cells: dict
    said: str
    nbytes: int
    img: np.ndarray
    eye: np.ndarray | None = None
    in_view: tuple = ()

    @property
    def measured(self) -> bool:
        return "camera_x" in self.cells


def read_unclipped(seen: Seen) -> bool:
    """The photo's spot was measured, and not so clipped that the measurement advises a lower exposure
    (:func:`vision.exposure.exposure_advice`: clipped over more than ``CLIPPED_MAX`` px)."""
    return seen.measured and "spot clipped over" not in seen.cells.get("camera_note", "")


def spot_cells(
    folder: Path,
    camera,
    measure,
    t: float,
    point: np.ndarray,
    meta: dict,
    img=None,
    policy: PhotoPolicy = ALL_PNG,
    first: bool = True,
) -> Seen:
    """Photograph a capture, measure its spot and keep the photo as ``policy`` says: the row's
    :data:`SPOT_COLUMNS` and the line(s) said at once.

    A spot that cannot be measured (hidden by the arm, outside the view, unreadable, two candidates)
    leaves ``camera_x``..``camera_sy`` empty and its reason in ``camera_note``. The spot is measured from
    the photo in memory: a photo not kept (:class:`~collector.sessions.photos.PhotoPolicy`) loses nothing
    of the measurement.

    Parameters
    ----------
    folder : Path, the session folder (photos/ is made in it)
    camera, measure : see :func:`run_capture`
    t : float, the capture's session time, s (names the photo: unique across resumes)
    point : (3,) array, where the spot was aimed, base frame at the placement (the message's distance), mm
    meta : dict, session.yaml (a sheet's placement maps the measured spot to the base frame)
    img : (h, w, 3) array or None, the photo if already taken (None: taken here)
    policy : PhotoPolicy, which photos are written and how
    first : bool, the first capture at its point (``--photos first`` keeps it)
    """
    from lasercal.collector.sessions.store import write_atomic_bytes
    from lasercal.vision.errors import VisionError

    img = camera.photo() if img is None else img
    name = f"photos/capture_{int(round(t * 1000)):09d}.{policy.fmt}"
    try:
        m = measure(img, name)
    except VisionError as e:
        eye, in_view = None, ()
        why = (str(e).split(": ", 1)[-1] if str(e).startswith(name) else str(e)).replace("\n", " ")
        cells, said = (
            {"photo": name, "camera_note": why},
            f"  ! camera: the spot could not be measured ({why})",
        )
    else:
        eye, in_view = m.eye, m.in_view
        cells = {"photo": name, "camera_x": m.xy[0], "camera_y": m.xy[1], "camera_sx": m.sigma[0]}
        cells.update(camera_sy=m.sigma[1], camera_note=m.note.replace("\n", " "))
        if m.eye is not None:  # where the camera stood: the fit's view of a curled paper (eq. S8)
            cells.update(zip(EYE_XYZ, np.round(np.asarray(m.eye, dtype=float), 3)))
        layout = session_layout(meta, folder)
        said = f"  camera: spot at ({m.xy[0]:.3f}, {m.xy[1]:.3f}) mm +- ({m.sigma[0]:.3f}, {m.sigma[1]:.3f})"
        if (
            layout.frame != "sheet" or layout.sheet is not None
        ):  # where the placement puts it: the cross's frame
            where = layout.sheet.to_base(m.xy[None], layout.plane_z)[0] if layout.frame == "sheet" else m.xy
            said += f", {np.hypot(*(np.asarray(where)[:2] - point[:2])):.1f} mm from the aim"
        said += "\n"
    data = b"" if policy.keep == "none" else policy.encode(img, name)
    if policy.kept(first, "camera_x" in cells):
        (folder / "photos").mkdir(exist_ok=True)
        write_atomic_bytes(folder / name, data)  # before the row: a row never names a missing photo
    else:
        cells["photo"] = ""
    return Seen(cells, said, len(data), img, eye, in_view)


class PhotoStep:
    """The photo step of a capture run (:class:`~collector.sessions.capture.CaptureRun`, whose state it
    reads and sets: the camera and its exposure, the point and aim under way, the standstill read)."""

    def photograph(self, t: float):
        """Photograph the capture under way and measure its spot; settle the exposure first until a spot is
        read unclipped.

        Parameters
        ----------
        t : float
            The capture's session time, s.

        Returns
        -------
        step : callable or None
            Where the run goes instead of recording the capture (None: record it): ``settle`` again when the
            arm moved while photographed, ``next_capture`` when a hands-free pose's spot was not measured.
        got : Seen
            What the camera made of it.
        seen : str
            The line(s) said about it.
        """
        name, aim, opts, counts = self.name, self.aim, self.opts, self.counts
        store, state, camera = self.store, self.still, self.camera
        self.state.phase("photo", "photographing the spot")
        # the exposure is set with the laser on a point, and again at each capture until a photo's spot
        # was read unclipped: a first spot off the markers' area, or one that clips later, does not fix it
        first = None if self.settled else settle_exposure(camera, readable_by(self.measure))
        aimed_at = self.points[name] if aim is None else aim[1]
        got = spot_cells(
            store.folder,
            camera,
            self.measure,
            t,
            aimed_at,
            self.meta,
            first,
            opts.photos,
            counts[name] == 0,
        )
        self.settled = self.settled or read_unclipped(got)
        self.sight_from(got.eye, got.in_view)
        if first is not None and not self.estimated:  # the run's first photo: what the photos will take
            self.estimated = True
            left = sum(max(opts.per_point - k, 0) for k in counts.values())
            self.say(estimate_line(opts.photos, got.nbytes, left, len(self.requested)) + "\n")
        moved = moved_during_photo(self.robot, state, self.nominal, self.layout.plane_z)
        if moved > PHOTO_MOVED_MM and self.photo_tries < PHOTO_TRIES:
            self.photo_tries += 1
            self.say(
                f"  the arm moved the spot {moved:.3f} mm while photographed (more than "
                f"{PHOTO_MOVED_MM:g}): photographing again once it is still\n"
            )
            return self.settle, got, ""
        self.photo_tries = 0
        seen = got.said
        if got.measured:
            return None, got, seen
        if self.hands_free and not self.by_hand:  # no aim and no measurement: no data
            why = got.cells["camera_note"]
            self.say(f"{seen}: not kept; this pose is guided by hand once: aim beside the cross, trigger\n")
            self.state.problem(f"the camera could not measure the spot ({why}): guided by hand once", got.img)
            self.by_hand = True
            return self.next_capture, got, seen
        seen += (
            ": kept as an aimed capture, fitted to where it was aimed with the aiming noise "
            "(d Enter discards it, to retake it)\n"
        )
        self.state.problem(
            f"the camera could not measure the spot ({got.cells['camera_note']}): kept as an aimed capture",
            got.img,
        )
        return None, got, seen
