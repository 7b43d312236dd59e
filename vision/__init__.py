"""lasercal vision: laser-spot measurement in photos, sub-pixel and in millimetres.

Replaces measuring spots by hand in ImageJ (thesis Section 4.3): detect the laser
spot(s) in a top-view photo, measure their centroids in pixels (OpenCV convention,
pixel centres at integer coordinates; ImageJ's is +0.5 px) and map them to mm on the
table plane in the robot base frame through printed ArUco/ChArUco markers.

Stands alone: imports neither ``solver`` nor ``collector``.
"""

from lasercal.vision.beamcheck import Circle, fit_circle, tilt
from lasercal.vision.camera import Camera, calibrate, load_camera, save_camera
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import (
    CalibrationError,
    ImageReadError,
    LayoutError,
    MarkerError,
    NoSpotError,
    SpotCountError,
    VisionError,
)
from lasercal.vision.exposure import Exposure, exposure_advice
from lasercal.vision.images import read_image
from lasercal.vision.measure import Options, PhotoResult, measure_batch, measure_file, measure_photo
from lasercal.vision.plane import MarkerLayout, PlaneMap, find_fiducials, fit_plane, load_markers
from lasercal.vision.spot import Evidence, Spot

__all__ = [
    "CalibrationError",
    "Camera",
    "Circle",
    "Evidence",
    "Exposure",
    "ImageReadError",
    "LayoutError",
    "MarkerError",
    "MarkerLayout",
    "NoSpotError",
    "Options",
    "PhotoResult",
    "PlaneMap",
    "Spot",
    "SpotCountError",
    "VisionError",
    "calibrate",
    "detect_spots",
    "exposure_advice",
    "find_fiducials",
    "fit_circle",
    "fit_plane",
    "load_camera",
    "load_markers",
    "measure_batch",
    "measure_file",
    "measure_photo",
    "read_image",
    "save_camera",
    "tilt",
]
