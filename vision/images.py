"""Reading photos.

Images are kept as OpenCV reads them: BGR (or grey) arrays of uint8 or uint16,
pixel (row v, column u), OpenCV pixel convention (pixel centres at integer
coordinates). EXIF orientation is ignored on purpose: every coordinate is in the
stored pixel grid, the sensor's own frame, which the camera model, the markers and
ImageJ all work in; a phone that flags some photos as rotated would otherwise mix two
frames. Only what a person looks at (the overlay) is turned upright, with
:func:`exif_orientation` and :func:`upright`.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

from lasercal.vision.errors import ImageReadError

_FLAGS = cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR | cv2.IMREAD_IGNORE_ORIENTATION


def read_image(path) -> np.ndarray:
    """Read a photo as it was recorded.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    (h, w, 3) BGR or (h, w) grey array, uint8 or uint16

    Raises
    ------
    ImageReadError
        The file is missing, unreadable or not an image OpenCV can decode.
    """
    path = Path(path)
    if path.is_dir():
        raise ImageReadError(f"{path}: is a folder (expected a photo; give its files, e.g. {path}/*.jpg)")
    if not path.is_file():
        raise ImageReadError(f"{path}: no such file")
    try:
        data = np.fromfile(path, np.uint8)
    except OSError as exc:
        raise ImageReadError(f"{path}: cannot read ({exc.strerror})") from None
    with _c_stderr() as said:  # the codecs' C libraries print to fd 2: lasercal's one line says it
        img = cv2.imdecode(data, _FLAGS) if data.size else None
    cut = _png_cut(data)
    if cut:  # checked whatever the decoder made of it (some versions return the part they read)
        raise ImageReadError(f"{path}: {cut}")
    why = _codec_complaint(said)
    if img is None and why:
        raise ImageReadError(f"{path}: cannot decode the photo ({why}): the file is damaged")
    if img is None:
        raise ImageReadError(f"{path}: not an image OpenCV can decode (JPEG, PNG, TIFF, ...)")
    if "premature end" in why.lower():  # libjpeg decodes a cut JPEG in part, the rest grey
        raise ImageReadError(f"{path}: the photo is cut short ({why}): only part of it could be decoded")
    if img.dtype not in (np.uint8, np.uint16):
        raise ImageReadError(f"{path}: {img.dtype} pixels are not supported (8- or 16-bit only)")
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]  # alpha carries no light
    elif img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    return np.ascontiguousarray(img)


@contextmanager
def _c_stderr():
    """Collect what C code writes to file descriptor 2 while the block runs (libpng's and libjpeg's
    messages bypass Python), into the list yielded: one string, once the block ends."""
    said: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield said
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            said.append(tmp.read().decode("utf-8", "replace"))


def _codec_complaint(said: list[str]) -> str:
    """The last line a codec library printed (e.g. ``IDAT: CRC error``), its prefix (``libpng error:``,
    OpenCV's ``[ WARN:0@1.6] global grfmt_png.cpp:793 readFromStreamOrBuffer``) dropped; "" when it
    printed nothing."""
    lines = [ln.strip() for ln in "".join(said).splitlines() if ln.strip()]
    if not lines:
        return ""
    last = re.sub(r"^\[[^]]*\]\s*global\s+\S+\s+\S+\s+", "", lines[-1])
    return re.sub(r"^lib\w+ (error|warning):\s*", "", last)


_PNG = b"\x89PNG\r\n\x1a\n"


def _png_cut(data: np.ndarray) -> str:
    """Why a PNG file ends before its last chunk (IEND), or "" (complete, or not a PNG). Each chunk is
    its 4-byte length, 4-byte type, its data and a 4-byte CRC."""
    buf = data.tobytes()
    if not buf.startswith(_PNG):
        return ""
    pos = len(_PNG)
    while pos + 8 <= len(buf):
        end = pos + 12 + int.from_bytes(buf[pos : pos + 4], "big")
        if end > len(buf):
            return f"the PNG is cut short: {len(buf)} bytes, where its chunks need at least {end}"
        if buf[pos + 4 : pos + 8] == b"IEND":
            return ""
        pos = end
    return f"the PNG is cut short: {len(buf)} bytes, and its last chunk (IEND) missing"


def full_scale(img: np.ndarray) -> float:
    """The saturation level of an image's pixels, DN."""
    return float(np.iinfo(img.dtype).max)


def all_at_least(img: np.ndarray, level: float) -> np.ndarray:
    """(h, w) bool: pixels whose every channel is at least ``level`` -- ``(img >= level).all(axis=2)``,
    channel by channel: numpy's reduction over a last axis of three is 7x slower (29 ms of a full-HD
    photo; a photo's measurement asks it of the whole photo three times)."""
    out = img[..., 0] >= level
    for k in range(1, img.shape[2]):
        out &= img[..., k] >= level
    return out


def to_gray(img: np.ndarray) -> np.ndarray:
    """Grey uint8 copy for marker and pattern detection."""
    g = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    return g if g.dtype == np.uint8 else (g >> 8).astype(np.uint8)


_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def chroma_subsampled(path) -> bool:
    """Whether a file is a JPEG that keeps its colour planes at lower resolution than
    its luma (4:2:0, 4:2:2: what most cameras write). False for anything else.

    Such a photo's red channel is rebuilt from half-resolution colour, so the precise
    centroid uses the luma, the only plane kept at full resolution.
    """
    try:
        with open(path, "rb") as fh:
            if fh.read(2) != b"\xff\xd8":
                return False
            while True:
                marker = fh.read(2)
                if len(marker) < 2 or marker[0] != 0xFF:
                    return False
                size = int.from_bytes(fh.read(2), "big")
                if marker[1] in _SOF:
                    seg = fh.read(size - 2)
                    factors = {seg[7 + 3 * i] for i in range(seg[5])}  # (H << 4 | V) per component
                    return len(factors) > 1
                fh.seek(size - 2, 1)
    except (OSError, IndexError):
        return False


def exif_orientation(path) -> int:
    """The EXIF orientation tag (274) of a photo file: 1 (upright, also when absent) to 8.

    Read with Pillow (a dependency of matplotlib), header only.
    """
    try:
        from PIL import Image

        with Image.open(path) as im:
            o = int(im.getexif().get(274, 1))
    except (ImportError, OSError, ValueError, SyntaxError):
        return 1
    return o if 1 <= o <= 8 else 1


def upright(img: np.ndarray, orientation: int) -> np.ndarray:
    """The photo as a viewer shows it: the stored grid turned as its EXIF orientation says.

    Parameters
    ----------
    img : (h, w[, c]) array in the stored grid; orientation : int, EXIF tag 274 (1-8)

    Returns
    -------
    array, (h, w[, c]) for 1-4 and (w, h[, c]) for 5-8
    """
    turn = {
        2: lambda a: cv2.flip(a, 1),
        3: lambda a: cv2.rotate(a, cv2.ROTATE_180),
        4: lambda a: cv2.flip(a, 0),
        5: lambda a: cv2.transpose(a),
        6: lambda a: cv2.rotate(a, cv2.ROTATE_90_CLOCKWISE),
        7: lambda a: cv2.flip(cv2.rotate(a, cv2.ROTATE_90_CLOCKWISE), 0),
        8: lambda a: cv2.rotate(a, cv2.ROTATE_90_COUNTERCLOCKWISE),
    }.get(orientation)
    return img if turn is None else turn(img)


def upright_points(uv: np.ndarray, shape: tuple, orientation: int) -> np.ndarray:
    """Where points of the stored grid land in :func:`upright`'s image.

    Parameters
    ----------
    uv : (n, 2) array, px in the stored grid (pixel centres at integers); shape : (h, w, ...) stored
    orientation : int, EXIF tag 274

    Returns
    -------
    (n, 2) array, px in the upright image
    """
    h, w = shape[:2]
    u, v = np.asarray(uv, float).T
    return np.column_stack(
        {
            2: (w - 1 - u, v),
            3: (w - 1 - u, h - 1 - v),
            4: (u, h - 1 - v),
            5: (v, u),
            6: (h - 1 - v, u),
            7: (h - 1 - v, w - 1 - u),
            8: (v, w - 1 - u),
        }.get(orientation, (u, v))
    )
