"""Cramér-Rao bounds of the centre of dim red laser spots on phone photos, against the detector.

Run from the repository root::

    PYTHONPATH=ENV python benchmarks/bench_vision_crb.py      # ~17 min on 2 busy cores, ~8 s a photo
    python benchmarks/bench_vision_crb.py --quick             # ~4 min, 8 photos per row

(``ENV``: a folder holding ``lasercal`` when the package is not installed.)

The photos are those of ``bench_vision_phone.py`` (same generator, same seeds): per row (red,
exposure, speckle) the first ``--photos`` spots the detector finds unclipped. For each photo the
bound follows from the renderer's own model (``vision.render`` with ``PhoneCamera``), in a window
of W x W px around the spot, at the raw Bayer photosites i (DN after auto exposure gain g):

    mean       mu_i = g (b_i + P r_c(i) G_i(u, v, sigma, aspect, angle))
    covariance Sigma = diag(read^2 + shot mu_i) + s^2 (rho^2 o L L^T),  L_i = g P r_c(i) G_i

G is the pixel-integrated elliptical Gaussian, r_c the Bayer filters' response to the laser (red
1, green 0.10, blue 0.04), b the paper's light. Speckle is the multiplicative field 1 + s (I - 1)
of contrast s; I = |f|^2 of a complex white field blurred by a Gaussian kernel k, so its
covariance is rho(d)^2, rho the normalised autocorrelation of k (separable in x and y). The
Fisher information of theta = (u, v, amplitude, sigma, aspect, angle, a background plane per
colour site) is, in the Gaussian approximation,

    J = dmu^T Sigma^-1 dmu,        CRB(u, v) = [J^-1] on the (u, v) block,

printed per axis, sqrt(trace / 2), as the RMS over the photos (like the detector's error).

Through the camera the photo is, linearised at the mean, z = K x + e8 + eq: K = T C D with D
the demosaicing (OpenCV's, linear), C per pixel the tone curve's slope x CCM x white balance,
T the JPEG's BGR -> YCbCr, 4:2:0 averaging and 8 x 8 DCT (orthonormal, as JPEG's); e8 the
rounding to 8 bits (1/12 DN^2 on each of B, G, R) and eq the quantisation of each coefficient,
taken as uniform noise of variance q^2 / 12 with q from libjpeg's tables scaled by the photo's
quality. Then Sigma_z = K Sigma K^T + T T^T / 12 + diag(q^2 / 12), J_z = (K dmu)^T Sigma_z^-1
(K dmu). Columns: raw Bayer (J), + 8-bit (without eq), + JPEG (with eq).

Approximations: noise and speckle as Gaussian; the information in how Sigma moves with theta
(the 1/2 tr(Sigma^-1 dSigma Sigma^-1 dSigma) term) is left out; the pipeline is linear at the
mean; the uniform model of quantisation holds where the noise reaching a coefficient exceeds its
step. Where the step is coarser the error is a function of the signal, not independent noise, so
the "+ JPEG" column is an approximation, not a strict bound.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import scipy.linalg as sla
import scipy.sparse as sps

from lasercal.vision import render as R
from lasercal.vision.detect import detect_spots
from lasercal.vision.errors import VisionError

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_vision_phone import EXPOSURES, spot_scene  # noqa: E402  the sweep's photos, same seeds

ROWS = ((0.3, 0.0), (0.3, 0.1), (0.3, 0.2), (0.5, 0.2))  # red: exposure, speckle
N, M = 48, 2  # JPEG window: whole 16 x 16 MCUs of 4:2:0; M: the margin demosaicing reaches into
W = N + 2 * M  # raw window, px
LUMA_Q = np.array(  # libjpeg's base tables (JPEG standard, Annex K)
    [
        [16, 11, 10, 16, 24, 40, 51, 61],
        [12, 12, 14, 19, 26, 58, 60, 55],
        [14, 13, 16, 24, 40, 57, 69, 56],
        [14, 17, 22, 29, 51, 87, 80, 62],
        [18, 22, 37, 56, 68, 109, 103, 77],
        [24, 35, 55, 64, 81, 104, 113, 92],
        [49, 64, 78, 87, 103, 121, 120, 101],
        [72, 92, 95, 98, 112, 100, 103, 99],
    ]
)
CHROMA_Q = np.full((8, 8), 99)
CHROMA_Q[:4, :4] = [[17, 18, 24, 47], [18, 21, 26, 66], [24, 26, 56, 99], [47, 66, 99, 99]]
BGR_TO_YCC = np.array([[0.114, 0.587, 0.299], [0.5, -0.3313, -0.1687], [-0.0813, -0.4187, 0.5]])


def quant_steps(quality: int) -> np.ndarray:
    """q of every coefficient of the window: libjpeg's jpeg_set_quality scaling of the base tables."""
    scale = 5000 / quality if quality < 50 else 200 - 2 * quality
    q = [np.clip((t * scale + 50) // 100, 1, 255) for t in (LUMA_Q, CHROMA_Q)]
    luma, chroma = np.tile(q[0], (N // 8, N // 8)).ravel(), np.tile(q[1], (N // 16, N // 16)).ravel()
    return np.concatenate([luma, chroma, chroma])


def jpeg_transform() -> sps.csr_matrix:
    """T: encoded BGR of the N x N window, index (y, x, c) -> DCT coefficients of Y, Cb, Cr (4:2:0)."""
    k = np.arange(8)
    d8 = np.sqrt(np.where(k == 0, 1, 2)[:, None] / 8) * np.cos(np.pi * (2 * k[None, :] + 1) * k[:, None] / 16)

    def block_dct(n):  # vec(D X D^T) = kron(D, D) vec(X), D = one 8 x 8 DCT per block of the n x n plane
        d = sps.kron(sps.identity(n // 8), d8)
        return sps.kron(d, d)

    half = sps.kron(sps.identity(N // 2), [[0.5, 0.5]])  # 4:2:0: the mean of each 2 x 2
    plane = [sps.kron(sps.identity(N * N), BGR_TO_YCC[c]) for c in range(3)]
    chroma = [block_dct(N // 2) @ sps.kron(half, half) @ p for p in plane[1:]]
    return sps.vstack([block_dct(N) @ plane[0]] + chroma).tocsr()


def demosaic_matrix() -> sps.csr_matrix:
    """D: raw window (W*W) -> BGR (W*W*3), OpenCV's RGGB demosaicing, exact as it is linear.

    Impulses 4 px apart do not overlap (each reaches 1 px), so 16 renders give every column;
    a 32768 offset and x4096 scale carry signed fractions through OpenCV's 16-bit integers.
    """
    rows, cols, vals = [], [], []
    for oy in range(4):
        for ox in range(4):
            raw = np.zeros((W, W))
            raw[oy::4, ox::4] = 4096.0
            out = cv2.cvtColor(np.uint16(raw + 32768), cv2.COLOR_BayerBG2BGR) / 4096.0 - 8.0
            ys, xs, cs = np.nonzero(np.abs(out) > 1e-6)
            sy = oy + 4 * np.round((ys - oy) / 4).astype(int)  # the impulse each output came from
            sx = ox + 4 * np.round((xs - ox) / 4).astype(int)
            ok = (sy >= 0) & (sy < W) & (sx >= 0) & (sx < W)
            rows.append(((ys * W + xs) * 3 + cs)[ok])
            cols.append((sy * W + sx)[ok])
            vals.append(out[ys, xs, cs][ok])
    ij = (np.concatenate(rows), np.concatenate(cols))
    return sps.csr_matrix((np.concatenate(vals), ij), (3 * W * W, W * W))


T, DEM = jpeg_transform(), demosaic_matrix()
ROUNDING = (T @ T.T).toarray() / 12  # 8-bit rounding of each encoded B, G, R: 1/12 DN^2, independent
INNER = np.nonzero(np.pad(np.ones((N, N, 3), bool), ((M, M), (M, M), (0, 0))).ravel())[0]


def speckle_corr(grain: float, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """rho(dx, dy): normalised autocorrelation of the kernel render blurs the speckle field with."""
    k = max(grain / 2, 0.3)
    g = cv2.getGaussianKernel(int(round(8 * k + 1)) | 1, k)[:, 0]
    a = np.correlate(g, g, "full") / np.dot(g, g)
    c = len(a) // 2
    return np.prod([np.where(np.abs(d) <= c, a[np.clip(c + d, 0, 2 * c)], 0.0) for d in (dx, dy)], 0)


def window_model(photo: R.Photo, seed: int):
    """mu, dmu (rows: theta), L and the raw noise variance on the W x W window around the spot."""
    spot, cam = photo.spots[0], photo.camera
    light = R.scene_light(dataclasses.replace(photo, spots=(dataclasses.replace(spot, speckle=0.0),)), None)
    # Auto exposure as render's _phone meters it (the spot's own light included).
    gain = cam.gain(seed) * cam.ae_target * R.FULL / max(float(np.median(light[::8, ::8, 1])), 1e-3)
    # JPEG blocks are aligned to the photo's origin: the window starts on a 16-px MCU corner.
    x0, y0 = (16 * np.round((np.array([spot.u, spot.v]) - N / 2) / 16)).astype(int) - M
    yy, xx = np.mgrid[y0 : y0 + W, x0 : x0 + W]
    site = np.where((yy % 2 == 0) & (xx % 2 == 0), 2, np.where((yy % 2 == 1) & (xx % 2 == 1), 0, 1))  # RGGB
    mu = gain * np.take_along_axis(light[y0 : y0 + W, x0 : x0 + W], site[..., None], 2)[..., 0]
    resp = gain * R.FULL * R.LASER_RESPONSE[photo.colour][site]

    def laser(**change):
        return resp * spot.peak * R._gaussian(dataclasses.replace(spot, **change), x0, y0, W, W)

    def deriv(name, h):  # central difference of the renderer's own pixel-integrated spot
        v = getattr(spot, name)
        return (laser(**{name: v + h}) - laser(**{name: v - h})) / (2 * h)

    L = laser()
    plane = [np.ones((W, W)), (xx - xx.mean()) / W, (yy - yy.mean()) / W]
    nuisance = [L / spot.peak] + [deriv(k, 1e-3) for k in ("sigma", "aspect", "angle_deg")]
    nuisance += [gain * (site == s) * p for s in range(3) for p in plane]  # paper's light under the spot
    dmu = np.array([x.ravel() for x in [deriv("u", 1e-3), deriv("v", 1e-3)] + nuisance])
    var = photo.read_noise**2 + photo.shot_noise * np.maximum(mu.ravel(), 0)
    return mu.ravel(), dmu, L.ravel(), var


def fisher(dmu: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """J = dmu^T Sigma^-1 dmu, the mean's term of a Gaussian's information (rows of dmu: theta)."""
    return dmu @ sla.cho_solve(sla.cho_factor(cov), dmu.T)


def centre_crb(J: np.ndarray) -> float:
    """Per-axis bound of the centre, sqrt(tr([J^-1]_uv) / 2): the nuisance parameters' cost included."""
    return float(np.sqrt(np.trace(np.linalg.inv(J)[:2, :2]) / 2))


def bounds(photo: R.Photo, seed: int) -> tuple[float, float, float]:
    """Raw Bayer, + 8-bit and + JPEG bounds of one photo, px per axis."""
    spot, cam = photo.spots[0], photo.camera
    mu, dmu, L, var = window_model(photo, seed)
    # Speckle covariance s^2 rho^2 L L^T, kept where the laser is above 1e-3 of its peak.
    lit = np.nonzero(L > 1e-3 * L.max())[0]
    yy, xx = np.divmod(lit, W)
    rho = speckle_corr(spot.grain, np.subtract.outer(xx, xx), np.subtract.outer(yy, yy))
    speckle = spot.speckle**2 * rho**2 * np.outer(L[lit], L[lit])
    # Raw: speckle couples only the lit photosites, so Sigma is block diagonal (lit block + the rest).
    dark = np.setdiff1d(np.arange(W * W), lit)
    J_raw = fisher(dmu[:, lit], np.diag(var[lit]) + speckle) + (dmu[:, dark] / var[dark]) @ dmu[:, dark].T
    # K = T C D, C the pipeline's per-pixel 3 x 3 slope at the mean: d(encoded DN) / d(raw DN).
    wb = 1 / np.asarray(photo.tint, float)
    colour = np.asarray(cam.ccm, float) * (wb / wb.min())[None, :] / R.FULL
    lin = (DEM @ mu).reshape(-1, 3) @ colour.T
    h = 1e-4
    slope = R.FULL * (R._tone(lin + h, cam.contrast) - R._tone(lin - h, cam.contrast)) / (2 * h)
    blocks = slope[:, :, None] * colour[None]
    idx = np.arange(3 * W * W).reshape(-1, 3)
    ij = (idx[:, :, None].repeat(3, 2).ravel(), idx[:, None, :].repeat(3, 1).ravel())  # (3p + c, 3p + k)
    C = sps.csr_matrix((blocks.ravel(), ij), (3 * W * W, 3 * W * W))
    K = (T @ (C @ DEM)[INNER]).tocsr()
    K_lit = K[:, lit].toarray()
    cov_z = (K @ sps.diags(var) @ K.T).toarray() + K_lit @ speckle @ K_lit.T + ROUNDING
    dz = (K @ dmu.T).T
    quant = np.diag(quant_steps(cam.jpeg).astype(float) ** 2 / 12)
    return centre_crb(J_raw), centre_crb(fisher(dz, cov_z)), centre_crb(fisher(dz, cov_z + quant))


def row(exposure: float, speckle: float, n: int):
    """The first n unclipped photos of the sweep's red row (80 photos): bounds, detector's errors."""
    rng = np.random.default_rng([int(speckle * 100), EXPOSURES.index(exposure), True])  # as the sweep's
    b, err = [], []
    for i in range(80):
        uv, photo = spot_scene(rng, "red", exposure, speckle)
        seed = 1000 * EXPOSURES.index(exposure) + i
        try:
            spots, _ = detect_spots(R.render(photo, seed), colour="auto", luma=True)
        except VisionError:
            continue
        s = min(spots, key=lambda s: np.hypot(s.u - uv[0], s.v - uv[1]))
        if s.saturated:
            continue
        b.append(bounds(photo, seed))
        err.append([s.u - uv[0], s.v - uv[1]])
        if len(b) == n:
            break
    return np.array(b), np.array(err)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", type=int, default=30, help="unclipped photos per row (default 30; 80: all)")
    ap.add_argument("--quick", action="store_true", help="8 photos per row (~4 min)")
    args = ap.parse_args()
    n = 8 if args.quick else args.photos
    t0 = time.time()
    print(f"Per-axis RMS over the first {n} unclipped photos of each red row of bench_vision_phone, px")
    print(f"{'red row':<20} {'n':>3} {'raw Bayer':>9} {'+ 8-bit':>8} {'+ JPEG':>7} {'detector':>9}")
    for exposure, speckle in ROWS:
        b, err = row(exposure, speckle, n)
        rms = np.sqrt(np.mean(b**2, 0))
        print(
            f"{f'{exposure}x, speckle {speckle}':<20} {len(b):>3} {rms[0]:9.3f} {rms[1]:8.3f} {rms[2]:7.3f} "
            f"{np.sqrt(np.mean(err**2)):9.3f}",
            flush=True,
        )
    print(f"\n(benchmark took {time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
