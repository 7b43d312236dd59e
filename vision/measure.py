"""One photo in, spots in pixels and millimetres out: the pipeline behind the CLI.

Pixels in OpenCV's convention (ImageJ's is +0.5 px, applied only on output), mm
in the robot base frame on the layout's plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.vision.camera import Camera
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError
from lasercal.vision.images import read_image, to_gray
from lasercal.vision.plane import MarkerLayout, PlaneMap, find_fiducials, fit_plane
from lasercal.vision.spot import Spot, with_plane


@dataclass(frozen=True)
class Options:
    """How to measure (see ``lasercal spots --help``)."""

    method: str = "precise"  # precise | imagej
    imagej_mode: str = "centroid"  # centroid | com
    imagej_threshold: str = "default"  # default | otsu
    imagej_box: int = 64  # side of the box drawn around a spot, px; 0: the whole photo
    colour: str = "red"
    expect: int | None = 1  # None: any number of spots
    gamma: float = 2.2  # the photos' encoding gamma, for marker corners and spots on ink
    channel: str = "auto"  # precise centroid on: laser | luma | auto (luma for chroma-subsampled JPEGs)


@dataclass(frozen=True)
class PhotoResult:
    """Spots of one photo, with the warnings and the plane map (None without markers)."""

    name: str
    spots: list
    warnings: list
    plane: PlaneMap | None


def measure_photo(
    img: np.ndarray,
    name: str,
    opts: Options = Options(),
    layout: MarkerLayout | None = None,
    camera: Camera | None = None,
    reference: np.ndarray | None = None,
    subsampled: bool = False,
) -> PhotoResult:
    """Detect and measure the spots of one photo, on the plane when the layout has markers.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16
    name : str, for messages
    opts : Options
    layout : MarkerLayout or None
    camera : Camera or None, lens distortion to undo before the homography
    reference : laser-off photo like ``img`` or None
    subsampled : bool, the photo is a JPEG with chroma subsampling (see ``images.chroma_subsampled``)

    Raises
    ------
    VisionError
        No spot, too many spots, too few markers, wrong image size: the photo is lost.
    """
    size = (img.shape[1], img.shape[0])
    if camera is not None:
        camera.check_size(size, name)
    luma = opts.channel == "luma" or (opts.channel == "auto" and subsampled)
    spots, warnings = detect_spots(
        img,
        name,
        opts.colour,
        reference,
        opts.expect,
        opts.method,
        opts.imagej_mode,
        opts.imagej_threshold,
        opts.imagej_box,
        opts.gamma,
        luma,
    )
    plane = None
    if layout is not None:
        fid = find_fiducials(to_gray(img), layout, opts.gamma, camera)
        plane = fit_plane(fid, layout, camera, size, name)
        if fid.unknown_ids:
            warnings.append(f"markers not in the layout ignored: ids {', '.join(map(str, fid.unknown_ids))}")
        if (~plane.inliers).any():
            warnings.append(
                f"{int((~plane.inliers).sum())} fiducial corners disagree with the layout by more than "
                "2 mm and were left out (wrong id or corner order?)"
            )
        uv = np.array([[s.u, s.v] for s in spots])
        xy = plane.to_plane(uv)
        sig_uv = np.array([[s.sigma_u or 0.0, s.sigma_v or 0.0] for s in spots])
        sig_xy = plane.sigma_mm(uv, sig_uv)
        has_sigma = [s.sigma_u is not None for s in spots]
        spots = [
            with_plane(s, float(p[0]), float(p[1]), float(e[0]) if ok else None, float(e[1]) if ok else None)
            for s, p, e, ok in zip(spots, xy, sig_xy, has_sigma)
        ]
        outside = ~plane.inside(uv)
        if outside.any():
            warnings.append(
                f"{int(outside.sum())} spot(s) outside the area the markers span: mm extrapolated"
            )
    return PhotoResult(name, spots, warnings, plane)


def median_reference(paths: list[str]) -> np.ndarray:
    """Per-pixel median of a photo series: the laser-free background when the spot moves.

    Raises
    ------
    VisionError
        Fewer than 3 photos, or photos of different sizes.
    """
    if len(paths) < 3:
        raise VisionError(f"--reference median needs at least 3 photos of one view, got {len(paths)}")
    imgs = [read_image(p) for p in paths]
    if len({i.shape for i in imgs}) != 1:
        raise VisionError("--reference median: the photos differ in size")
    return np.median(np.stack(imgs), axis=0).astype(imgs[0].dtype)


def spot_dicts(spots: list[Spot], convention: str) -> list[dict]:
    """JSON-ready spots."""
    return [s.to_dict(convention) for s in spots]
