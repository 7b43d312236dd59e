"""Errors of the vision package: one base class, specific subclasses.

Every error raised on bad user input derives from :class:`VisionError`; the CLI
turns it into ``lasercal: error: <message>`` and exit code 2. Messages name the
file, and the field when there is one.
"""

from __future__ import annotations


class VisionError(Exception):
    """Base class of every error the vision package raises on purpose."""


class ImageReadError(VisionError):
    """An image file is missing, unreadable or not an image."""


class NoSpotError(VisionError):
    """No laser spot was found in an image."""


class SpotCountError(VisionError):
    """More spots were found than expected (e.g. two where one is expected)."""


class MarkerError(VisionError):
    """Too few fiducial markers were found to map pixels to millimetres."""


class LayoutError(VisionError):
    """A layout or camera YAML file is malformed; names the file and the field."""

    def __init__(self, path, message: str, field: str | None = None):
        self.path, self.field, self.reason = str(path), field, message
        where = self.path if field is None else f"{self.path}, field '{field}'"
        super().__init__(f"{where}: {message}")


class SheetError(VisionError):
    """A reference sheet cannot be laid out (a paper too small for its markers, scale bars and points)."""


class CalibrationError(VisionError):
    """Camera calibration or a circle fit could not be carried out."""


class MeasureFault(VisionError):
    """A fault inside the measurement of one photo (a library's assertion, a numerical failure),
    reported as one line naming the photo and the stage instead of a traceback."""
