"""Targeted extra paths: more samples where the denoiser cannot average (``bench/DENOISE.md``).

``dt-irradiance`` (:mod:`retarget.denoise`) averages a pixel with its neighbours that look alike in
its guide-only joint image. A pixel with no such neighbour (a sphere whose normal turns faster than
``sigma_normal`` per pixel, a one-pixel strip where two walls meet) keeps its own Monte-Carlo noise:
those pixels make the denoised cube's error tail.

- **Reach** (:func:`reach`): the per-pixel RMS of the filter applied to unit white noise (a fixed
  seed, ``REACH_CHANNELS`` channels) with the method's joint image: 1 where the filter leaves a pixel
  as it is, ~0.1 on a flat wall. It comes from the guides alone (the view's AOVs and the group's
  direct-light guide), so a pixel's sample count never depends on its own samples: the estimate
  stays unbiased.
- **Mask** (:func:`boost_mask`): surface pixels whose reach exceeds ``RenderSettings.boost_reach``.
- **Extra paths** (:func:`extra_path_sums`): the all-bands integrator run on camera rays of the
  listed pixels only (uniform sub-pixel jitter, an independent sampler with its own seed), its band
  AOVs summed per pixel in float64 (``numpy.bincount``, a fixed order: deterministic). The renderer
  (:mod:`renderer_jobs.mitsuba.band_render`) combines them with the film's estimate weighted by path
  counts, ``(n0·base + Σ extra)/(n0 + n1)``; every other pixel is left bit for bit as rendered.
"""

from __future__ import annotations

import numpy as np

from illumix.renderer_jobs.band_schedule import mix_seed

REACH_CHANNELS = 32  # white-noise channels whose RMS estimates the reach (its own noise ~1/√(2·32) = 12 %)
REACH_SEED = 0x0EAC4  # the noise image is fixed: the mask depends on the guides only
BOOST_SALT = 0xB0057  # mixed with the cube's seed: the extra paths' random numbers are their own


def reach(guides, method: str) -> np.ndarray:
    """``(H, W)`` float32: the RMS over ``REACH_CHANNELS`` unit white-noise channels after
    ``method``'s filter (``dt-irradiance``: its joint image
    :func:`retarget.denoise.irradiance_guide_image`, its ``sigma_spatial`` and iterations). Needs
    ``guides.direct``."""
    from illumix.retarget.denoise import dt_filter, irradiance_guide_image, method_params

    name, p = method_params(method)
    if name != "dt-irradiance":
        raise ValueError(f"targeted extra paths need the dt-irradiance denoiser (its reach), not {name!r}")
    joint = irradiance_guide_image(guides, p["sigma_normal"], p["sigma_depth"], p["sigma_direct"], p["albedo_floor"],
                                   sigma_spatial=p["sigma_spatial"], iterations=int(p["iterations"]))
    noise = np.random.default_rng(REACH_SEED).standard_normal((*guides.shape, REACH_CHANNELS)).astype(np.float32)
    out = dt_filter(noise, joint, p["sigma_spatial"], int(p["iterations"]))
    return np.sqrt(np.mean(np.square(out, dtype=np.float64), axis=-1)).astype(np.float32)


def boost_mask(guides, method: str, threshold: float) -> np.ndarray:
    """``(H, W)`` bool: surface pixels (hit, not an emitter) whose :func:`reach` exceeds ``threshold``."""
    return (reach(guides, method) > threshold) & guides.hit & ~guides.emitter


def extra_path_sums(ms, sensor, integrator, pix: np.ndarray, paths: int, seed: int, max_lanes: int,
                    wavelengths: np.ndarray) -> np.ndarray:
    """``(len(pix), n_aov)`` float64: the sums of ``integrator``'s AOVs over ``paths`` paths through
    each pixel of ``pix`` (flat row-major indices of ``sensor``'s film), uniformly jittered in the
    pixel (the box filter of the film render). ``wavelengths (4,)``: carried by the camera rays (the
    band integrator sets its own per path). At most ``max_lanes`` paths per Dr.Jit call."""
    from illumix.renderer_jobs.mitsuba.trace import camera_rays
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba

    mi, dr = import_mitsuba()
    w, h = (int(x) for x in sensor.film().crop_size())
    n_aov = len(integrator.aov_names())
    sums = np.zeros((len(pix), n_aov), np.float64)
    all_pix = np.repeat(np.arange(len(pix), dtype=np.int64), paths)
    sampler = mi.load_dict({"type": "independent"})
    lam = np.asarray(wavelengths, np.float32)
    for k, a in enumerate(range(0, len(all_pix), max(1, max_lanes))):
        rows = all_pix[a:a + max_lanes]
        key = mix_seed(seed, BOOST_SALT, k)
        jitter = np.random.default_rng([key & 0xFFFFFFFF, 0x717]).random((len(rows), 2), dtype=np.float32)
        sampler.seed(dr.opaque(mi.UInt32, key & 0xFFFFFFFF), len(rows))
        ray = camera_rays(mi, sensor, w, h, pix[rows], jitter, np.tile(lam, (len(rows), 1)), differential=True)
        _, _, aovs = integrator.sample(ms, sampler, ray, None, mi.Bool(True))
        dr.eval(aovs)
        for c, v in enumerate(aovs):  # one AOV at a time: memory of one lane block per column
            sums[:, c] += np.bincount(rows, weights=np.asarray(v, np.float64), minlength=len(pix))
    return sums


__all__ = ["BOOST_SALT", "REACH_CHANNELS", "boost_mask", "extra_path_sums", "reach"]
