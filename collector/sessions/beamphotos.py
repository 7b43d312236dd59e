"""The photos of a beam check taken live (``lasercal beam-check --device``): the operator turns joint 7 to
a new angle, keeps the spot in view and triggers; each photo is kept in a folder, then measured as the
photos ``beam-check IMAGE...`` is given. With ``--view`` the page shows the live frames (the spot and the
sheet's markers found), how many photos are taken and where the last spot was.
"""

from __future__ import annotations

import sys
from pathlib import Path

from lasercal.collector.errors import SessionError
from lasercal.collector.sessions.state import ACTIONS, EitherTrigger, SessionState


def take_beam_photos(camera, folder: Path, trigger, view=None, layout_file=None, out=sys.stdout) -> list[str]:
    """Photograph the spot at each joint-7 angle the operator triggers, until they quit.

    Parameters
    ----------
    camera : a camera (``photo()``, ``close()``)
    folder : Path, a new or empty folder: beam_NN.png
    trigger : Trigger, Enter captures, ``d`` discards the last photo, ``q`` ends
    view : collector.view.ViewOptions or None, serve the live view meanwhile
    layout_file : the layout whose markers the live frames are checked against, or None
    out : text stream, the operator's screen

    Returns
    -------
    list of str, the photos' paths, in order
    """
    import cv2

    from lasercal.collector.sessions.start import session_view
    from lasercal.collector.sessions.store import write_atomic_bytes
    from lasercal.collector.view.live import find_spot

    folder.mkdir(parents=True, exist_ok=True)
    if any(folder.iterdir()):
        raise SessionError(f"--save {folder}: not empty (expected a new or empty folder for the photos)")
    state = SessionState("beam-check", out)
    photos: list[Path] = []
    try:
        with session_view(state, view, camera, layout_file) as cam:
            trig = EitherTrigger(trigger, state) if view is not None else trigger
            while True:
                line = (
                    f"turn joint 7 to a new angle, the spot in view, then capture (photo {len(photos) + 1})"
                )
                state.phase("aiming", line, ACTIONS)
                state.update(progress=[{"name": "photos", "done": len(photos), "want": max(len(photos), 3)}])
                state.say(f"{line}   [{trigger.hint}; q: done]\n")
                cmd = trig.wait()
                if cmd == "quit":
                    break
                if cmd == "discard":
                    if photos:
                        photos.pop().unlink()
                        state.say("discarded the last photo\n")
                    continue
                state.phase("photo", "photographing the spot")
                img = cam.photo()
                path = folder / f"beam_{len(photos) + 1:02d}.png"
                write_atomic_bytes(path, cv2.imencode(".png", img)[1].tobytes())
                photos.append(path)
                spot = find_spot(img)
                where = "no spot found" if spot is None else f"spot near ({spot[0]:.0f}, {spot[1]:.0f}) px"
                state.update(last={"point": "photo", "number": len(photos), "measured": False, "flag": where})
                state.say(f"  {path}: {where}\n")
            state.end(f"{len(photos)} photos in {folder}: measuring them")
    finally:
        camera.close()
        trigger.close()
    return [str(p) for p in photos]
