"""More samples at chosen pixels: the people, which the denoiser leaves noisy.

OIDN takes the people's noise for detail: at 640x360 a person is 5 to 10
pixels wide, and every few pixels the albedo guide changes (skin, top,
trousers), so the network keeps what it sees there. On the benchmark's
museum frame (64 spp) it lowered the people's share of the error only
from 0.000134 to 0.000114, and the rest of the frame's from 0.000155 to
0.000037: the people, 4 % of the pixels, held three quarters of the
denoised error. More samples everywhere pay for the floor, which OIDN
cleans anyway; these are spent where the denoiser cannot help.

A people sample costs about 7 times an average one (their 1,450 triangles
each, in a crowd, against a floor of two); still, on that frame 64 spp
and 36 more on the people (2.83 s) come as close as 96 spp everywhere
(3.56 s; 0.00011 each), and 32 + 64 (the groundtruth preset, 2.17 s)
closer than 64 spp everywhere (2.59 s). They must be stratified: 64
more independent samples on the people, at the same cost, left
0.000121 where one multijitter sequence a pixel left 0.000095.

The samples are drawn as Mitsuba's own film draws them (the sensor's
sampler, each pixel's samples one stratified sequence; sub-pixel
position, then the aperture), traced by the scene's integrator, and
averaged here in a fixed order (the same bytes run after run). The pixel
count is padded up a geometric ladder so that frames whose crowd covers
a few more pixels reuse the compiled kernel (the JIT bakes the wavefront's
size in; a new size costs 0.3 s of compiling).
"""

from __future__ import annotations

import numpy as np

# Pixel counts are padded up to the next rung ceil(2^(j/4)): under a fifth more lanes past a few hundred
# pixels, few distinct kernels.
_LADDER_STEP = 2.0 ** 0.25
# At most this many lanes (pixels x samples) in one kernel launch: the film's own largest pass at 1920x1080
# and 64 spp. More pixels go in chunks of the same size (the same kernel; fixed bounds, so the same bytes).
MAX_LANES = 1920 * 1080 * 64
# Each further chunk's seed: this times its number past the first (a prime, as frame.py's seed offsets).
CHUNK_SEED = 7919


def padded_count(k: int) -> int:
    """The smallest rung of the ladder ``ceil(2^(j/4))``, j >= 0, that holds ``k`` pixels (``k`` >= 1)."""
    j = max(int(np.floor(4 * np.log2(max(int(k), 1)))) - 1, 0)
    while int(np.ceil(_LADDER_STEP ** j)) < k:
        j += 1
    return int(np.ceil(_LADDER_STEP ** j))


def sample_pixels(scene, pixels: np.ndarray, spp: int, seed: int) -> tuple[np.ndarray, int]:
    """Mean radiance of ``spp`` new samples in each of ``pixels``, through the scene's sensor and integrator.

    Parameters
    ----------
    scene : mitsuba.Scene
        With one sensor (box-filtered film) and a sampling integrator.
    pixels : (k,) int
        Flat pixel indices, ``row * width + column``.
    spp : int
        Samples per pixel; the sensor's sampler may round it (multijitter
        and stratified want a product of two counts).
    seed : int
        Seed of these samples (give the film's passes other seeds).

    Returns
    -------
    radiance : (k, 3) float32
        Linear RGB, each pixel's samples averaged (box filter).
    taken : int
        The samples each pixel got.

    Only on JIT RGB variants (``llvm_ad_rgb``, ``cuda_ad_rgb``), with an
    uncropped film.
    """
    import mitsuba as mi

    variant = mi.variant()
    if variant.startswith("scalar") or not variant.endswith("_rgb"):
        raise ValueError(f"samples at chosen pixels need a JIT RGB variant, not {variant}")
    pixels = np.asarray(pixels, dtype=np.int64).ravel()
    sensor = scene.sensors()[0]
    film = sensor.film()
    if any(int(v) for v in film.crop_offset()):
        raise ValueError("samples at chosen pixels need an uncropped film")
    width, height = (int(v) for v in film.crop_size())
    if len(pixels) and (pixels.min() < 0 or pixels.max() >= width * height):
        raise ValueError(f"pixel indices must lie in [0, {width * height}), not [{pixels.min()}, {pixels.max()}]")
    probe = sensor.sampler().clone()
    probe.set_sample_count(int(spp))
    n = int(probe.sample_count())                   # as the sampler rounds it
    chunk = max(1, MAX_LANES // n)
    parts = [_sample_chunk(scene, pixels[i:i + chunk], n, int(seed) + CHUNK_SEED * (i // chunk), width, height)
             for i in range(0, len(pixels), chunk)]
    return (np.concatenate(parts) if parts else np.zeros((0, 3), np.float32)), n


def _sample_chunk(scene, pixels: np.ndarray, n: int, seed: int, width: int, height: int) -> np.ndarray:
    """(k, 3) float32 mean of ``n`` samples (a count the sampler takes as it is) at each of ``pixels``."""
    import drjit as dr
    import mitsuba as mi

    k = len(pixels)
    sensor = scene.sensors()[0]
    sampler = sensor.sampler().clone()
    sampler.set_sample_count(n)
    k_pad = padded_count(k)
    lanes = k_pad * n
    sampler.set_samples_per_wavefront(n)            # each pixel's n lanes: one stratified sequence
    sampler.seed(dr.opaque(mi.UInt32, int(seed) & 0xFFFFFFFF), lanes)
    padded = np.zeros(k_pad, np.uint32)             # the padding lanes trace pixel 0 and are dropped
    padded[:k] = pixels
    pixel = dr.gather(mi.UInt32, mi.UInt32(padded), dr.arange(mi.UInt32, lanes) // n)
    # Mitsuba's film: position in the pixel first, then the aperture, then the shutter time.
    pos = mi.Point2f(mi.Float(pixel % width), mi.Float(pixel // width)) + sampler.next_2d()
    aperture = sampler.next_2d() if sensor.needs_aperture_sample() else mi.Point2f(0.5)
    time = sensor.shutter_open()
    if sensor.shutter_open_time() > 0:
        time += sampler.next_1d() * sensor.shutter_open_time()
    ray, weight = sensor.sample_ray(time, 0.5, pos / mi.ScalarVector2f(width, height), aperture)
    radiance, _, _ = scene.integrator().sample(scene, sampler, ray)
    # Summed here in one order (the JIT's atomic adds would not be): the same bytes run after run.
    lane_rgb = np.array(mi.Color3f(radiance) * weight, dtype=np.float32).reshape(3, k_pad, n)[:, :k]
    return (lane_rgb.sum(axis=2, dtype=np.float64) / n).T.astype(np.float32)


def merge_samples(beauty: np.ndarray, spp: int, pixels: np.ndarray, extra: np.ndarray, extra_spp: int) -> np.ndarray:
    """(h, w, 3) ``beauty`` (``spp`` samples a pixel) with ``extra`` ((k, 3), ``extra_spp`` each) averaged in.

    Each pixel becomes the mean of all its samples, so it stays an unbiased
    estimate; pixels not in ``pixels`` are untouched.
    """
    out = np.array(beauty, dtype=np.float32, copy=True)
    flat = out.reshape(-1, out.shape[-1])
    both = spp + extra_spp
    flat[pixels] = (flat[pixels].astype(np.float64) * (spp / both)
                    + extra.astype(np.float64) * (extra_spp / both)).astype(np.float32)
    return out
