"""Geometry AOVs of a view (albedo, per-band albedo, normal, depth, hit mask, emitter mask, straddle): the
denoising guides and the validity masks the service serves, from jittered primary rays (no path tracing)."""

from __future__ import annotations

import numpy as np

from illumix.renderer_jobs.cube import ALBEDO_BANDS  # noqa: F401 - every backend's albedo AOV (re-exported)
from illumix.renderer_jobs.mitsuba.denoise_guides import albedo_bands as spectral_albedo
from illumix.renderer_jobs.mitsuba.denoise_guides import guides_needed, straddle
from illumix.renderer_jobs.mitsuba.render import RenderSettings
from illumix.renderer_jobs.mitsuba.trace import Tracer
from illumix.scene.model import Scene



def render_aovs(scene: Scene, view: str, settings: RenderSettings = RenderSettings()) -> dict[str, np.ndarray]:
    """Geometry AOVs of a view, averaged over ``aov_spp`` jittered primary rays per pixel.

    albedo ``(H, W, 3)``: mean diffuse reflectance (Mitsuba's ``eval_diffuse_reflectance``) over
    600–700, 500–600, 400–500 nm (R, G, B); albedo_bands ``(H, W, bands)`` (when ``settings.denoise``
    reads it): the diffuse reflectance per band, exact at the band centres, over ``ALBEDO_RAYS``
    Hammersley positions per pixel (:mod:`renderer_jobs.mitsuba.denoise_guides`: the ``dt-irradiance``
    guide); straddle ``(H, W)`` bool (when ``settings`` denoise with it: with the targeted extra
    paths): the pixel's rays hit more than one surface (``renderer_jobs.mitsuba.denoise_guides.straddle``);
    normal ``(H, W, 3)``: world-space shading normal
    (unit, of the hits); depth ``(H, W)``: distance from the camera along the ray in metres (0 where
    nothing is hit); mask ``(H, W)`` bool: the pixel centre ray hits geometry; emitter ``(H, W)``
    bool: most of the pixel's rays hit a light source's own surface (any group's), where the
    illumination of a surface is not defined. float32 except mask, emitter and straddle.
    """
    tracer = Tracer(scene, view, None, settings.resolution)  # every emitter on: emitting shapes flagged
    w, h = tracer.width, tracer.height
    npix = w * h
    k = max(1, settings.aov_spp)
    rng = np.random.default_rng([settings.seed & 0xFFFFFFFF, 0xA0F])
    pix = np.repeat(np.arange(npix, dtype=np.int64), k)
    jitter = rng.random((len(pix), 2), dtype=np.float32)
    jitter[::k] = 0.5  # the first sample of every pixel is its centre (for the mask)
    u = rng.random((len(pix), 3))
    lam = np.empty((len(pix), 4), dtype=np.float32)
    for c, (a, b) in enumerate(ALBEDO_BANDS):
        lam[:, c] = a + (b - a) * u[:, c]
    lam[:, 3] = 550.0
    out = tracer.first_hit(pix, jitter, lam)
    hit = out["hit"].reshape(npix, k)
    hitf = hit.astype(np.float64)
    nh = np.maximum(hitf.sum(axis=1), 1)
    albedo = (out["albedo"][:, :3].reshape(npix, k, 3) * hitf[..., None]).sum(axis=1) / nh[:, None]
    normal = (out["normal"].reshape(npix, k, 3) * hitf[..., None]).sum(axis=1)
    norm = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(norm > 0, normal / np.where(norm > 0, norm, 1), 0.0)
    depth = (out["distance"].reshape(npix, k) * hitf).sum(axis=1) / nh
    emitter = out["emitter"].reshape(npix, k).mean(axis=1) > 0.5
    aovs = {"albedo": albedo.reshape(h, w, 3).astype(np.float32),
            "normal": normal.reshape(h, w, 3).astype(np.float32),
            "depth": depth.reshape(h, w).astype(np.float32),
            "mask": hit[:, 0].reshape(h, w),
            "emitter": emitter.reshape(h, w)}
    wanted = guides_needed(settings)
    if "albedo_bands" in wanted:
        aovs["albedo_bands"] = spectral_albedo(tracer)
    if "straddle" in wanted:
        aovs["straddle"] = straddle(tracer)
    return aovs
