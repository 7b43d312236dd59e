"""Which photos a capture or validation session keeps, in which format, and what that costs on disk.

Every photo is measured as it is taken, from the image in memory: its spot and sigma go into the session's
CSV whether the photo is kept or not, so keeping fewer or smaller photos loses no measurement. A kept
photo is evidence (``lasercal spots`` re-measures it); a photo whose spot could not be measured is always
kept unless ``--photos none``: it shows what went wrong (hidden by the arm, clipped, two candidates).

Sizes, measured on the fake sheet camera's 1280 x 960 photos (``python benchmarks/bench_photos.py``): a
PNG 1.44 MB (a noisy photo barely compresses: 65 MB for 45 captures), a JPEG at quality 95 0.14 MB (6.4
MB); the JPEG re-measured moves the spot by 0.023 mm RMS (0.045 mm at most over 10 spots, up to 2.4 times
the sigma of the sharpest spots): JPEG keeps evidence, the CSV keeps the measurement. Validation's 800 x 600
photos: 0.65 MB as PNG, 0.07 MB as JPEG (0.012 mm).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.collector.errors import DeviceError

KEEP = ("all", "first", "none")
FORMATS = ("png", "jpg")
JPEG_QUALITY = 95  # a spot's centre moves by half its sigma at most when re-measured (module docstring)


@dataclass(frozen=True)
class PhotoPolicy:
    """Which photos a session writes.

    Attributes
    ----------
    keep : str, ``all``: every photo; ``first``: the first at each point (a validation: its first
        configuration's) and every photo whose spot could not be measured; ``none``: no photo
    fmt : str, ``png`` (lossless) or ``jpg`` (quality :data:`JPEG_QUALITY`, a tenth of the size)
    """

    keep: str = "all"
    fmt: str = "png"

    @classmethod
    def of(cls, cfg: dict) -> PhotoPolicy:
        """The policy of a session's settings (``photos``, ``photo_format``; older sessions: all, png)."""
        return cls(cfg.get("photos") or "all", cfg.get("photo_format") or "png")

    def kept(self, first: bool, measured: bool) -> bool:
        """Whether a photo is written: the first of its point (or run), whether its spot was measured."""
        return self.keep == "all" or (self.keep == "first" and (first or not measured))

    def encode(self, img: np.ndarray, name: str) -> bytes:
        """The photo as the file's bytes (PNG or JPEG)."""
        import cv2

        params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if self.fmt == "jpg" else []
        ok, data = cv2.imencode(f".{self.fmt}", img, params)
        if not ok:
            raise DeviceError(f"cannot encode photo {name}")
        return data.tobytes()

    def expected(self, photos: int, points: int) -> int:
        """How many of ``photos`` photos over ``points`` points are written, at least (problems add)."""
        return {"all": photos, "first": min(points, photos), "none": 0}[self.keep]

    def words(self) -> str:
        """What is kept, in words: 'all, PNG', 'first, JPG', 'none: each photo is measured, then dropped'."""
        if self.keep == "none":
            return "none: each photo is measured, then dropped"
        return f"{self.keep}, {self.fmt.upper()}"

    def choices(self) -> str:
        """What else the options offer, for the line that says what a session writes."""
        if self.keep == "none":
            return "--photos first keeps the first at each point"
        other = [f"--photos {k}" for k in KEEP if k != self.keep and k != "all"]
        return " or ".join(other + ([] if self.fmt == "jpg" else ["--photo-format jpg"])) + " keep less"


ALL_PNG = PhotoPolicy()  # every photo, lossless: the default


def megabytes(nbytes: float) -> str:
    """A size in words: '64.8 MB', '412 kB'."""
    return f"{nbytes / 1e6:.1f} MB" if nbytes >= 1e6 else f"{nbytes / 1e3:.0f} kB"


def folder_bytes(folder: Path) -> tuple[int, int, int]:
    """What a session folder holds: all its files' bytes, its photos' bytes and their count."""
    files = [p for p in Path(folder).rglob("*") if p.is_file()]
    photos = [p for p in files if p.parent.name == "photos"]
    return sum(p.stat().st_size for p in files), sum(p.stat().st_size for p in photos), len(photos)


def written_line(folder: Path) -> str:
    """The session's end: what it wrote, e.g. 'wrote 65.1 MB in session: 45 photos 64.9 MB'."""
    total, photos, n = folder_bytes(folder)
    return f"wrote {megabytes(total)} in {folder}: {n} photo{'' if n == 1 else 's'} {megabytes(photos)}"


# Bytes per kept photo before the first is taken (then its own size is said): the fake camera's 1280 x 960
# photos, measured -- PNG 1.44 MB (1.18 bytes a pixel), JPEG at quality 95 142 kB (0.115); validate's
# 800 x 600 fake views 654 kB and 71 kB. A camera of another resolution scales them.
PHOTO_BYTES = {"png": 1.45e6, "jpg": 0.15e6}


def start_estimate_line(policy: PhotoPolicy, photos: int, points: int) -> str | None:
    """Said when a session starts, before anything is written: the disk its photos will need, about
    (None when it keeps none)."""
    n = policy.expected(photos, points)
    if policy.keep == "none" or n == 0:
        return None
    each = PHOTO_BYTES.get(policy.fmt, PHOTO_BYTES["png"])
    return (
        f"this session will write about {n * each / 1e6:.1f} MB: {n} photo{'' if n == 1 else 's'} at about "
        f"{megabytes(each)} each ({policy.fmt.upper()}, a 1280 x 960 camera's; the first photo tells)"
    )


def estimate_line(policy: PhotoPolicy, first_bytes: int, photos: int, points: int) -> str:
    """Said after a session's first photo (the first whose size is known): what its photos will take."""
    n = policy.expected(photos, points)
    if policy.keep == "none":
        return "photos: none kept (--photos none): each photo is measured, then dropped"
    return (
        f"photos: {megabytes(first_bytes)} each ({policy.fmt.upper()}): about {megabytes(n * first_bytes)} "
        f"for {n} photo{'' if n == 1 else 's'} (--photos {policy.keep}; {policy.choices()})"
    )
