"""Rays in, radiance out: Mitsuba's integrator driven on rays and wavelengths chosen by the caller.

:class:`Tracer` loads one (view, set of light groups) once (:func:`renderer_jobs.mitsuba_scene.
load_mitsuba_scene`) and traces batches of paths: pixel index, sub-pixel jitter and the four
wavelengths of each path come from numpy, the radiance goes back to numpy. This is what lets
:mod:`renderer_jobs.mitsuba_render` choose every wavelength (stratified bands) instead of Mitsuba's film.
"""

from __future__ import annotations

import numpy as np

from renderer_jobs.mitsuba_scene import load_mitsuba_scene
from renderer_jobs.mitsuba_variant import import_mitsuba
from renderer_jobs.scene_model import Scene


def _aligned(a: np.ndarray) -> np.ndarray:
    """A 64-byte aligned contiguous float32 copy: Dr.Jit emits different (uncached) kernels for
    differently aligned input buffers, so every input gets the same alignment."""
    a = np.asarray(a, dtype=np.float32).ravel()
    buf = np.empty(a.size + 16, dtype=np.float32)
    k = (-buf.ctypes.data % 64) // 4
    out = buf[k:k + a.size]
    out[...] = a
    return out


class Tracer:
    """Mitsuba scene + sensor + integrator for one (view, set of groups), reused across passes."""

    def __init__(self, scene: Scene, view: str, groups: list[str] | None, resolution=None, portals="without"):
        self.mi, self.dr = import_mitsuba()
        self.scene = scene
        self.ms, self.sensor = load_mitsuba_scene(scene, view, groups, resolution, portals=portals)
        self.integrator = self.ms.integrator()
        size = self.sensor.film().crop_size()
        self.width, self.height = int(size[0]), int(size[1])
        self.grid = scene.spectral_grid

    def trace(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, seed: int) -> np.ndarray:
        """Radiance ``(n, 4)`` float32 of paths through pixels ``pix`` (flat index, row-major from the
        top-left) at sub-pixel offsets ``jitter (n, 2)`` carrying ``wavelengths (n, 4)`` nm."""
        mi, dr = self.mi, self.dr
        n = len(pix)
        sampler = self.sensor.sampler().clone()
        sampler.seed(dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), n)
        ray = self._camera_rays(pix, jitter, wavelengths, differential=True)
        spec, valid, _ = self.integrator.sample(self.ms, sampler, ray, None, True)
        spec = mi.unpolarized_spectrum(spec)
        dr.eval(spec)
        out = np.stack([np.asarray(spec[i], dtype=np.float32) for i in range(4)], axis=1)
        return out

    def _camera_rays(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, differential: bool):
        """Camera rays through film position ``pixel + jitter`` carrying the 4 given wavelengths."""
        mi = self.mi
        px = (pix % self.width).astype(np.float32) + jitter[:, 0]
        py = (pix // self.width).astype(np.float32) + jitter[:, 1]
        pos = mi.Point2f(mi.Float(_aligned(px / self.width)), mi.Float(_aligned(py / self.height)))
        sample = self.sensor.sample_ray_differential if differential else self.sensor.sample_ray
        ray, _ = sample(0.0, mi.Float(0.5), pos, mi.Point2f(0.5, 0.5))
        ray.wavelengths = type(ray.wavelengths)(*[mi.Float(_aligned(wavelengths[:, i])) for i in range(4)])
        return ray

    def first_hit(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray) -> dict[str, np.ndarray]:
        """Primary-hit AOVs per sample: albedo ``(n, 4)``, normal ``(n, 3)``, distance ``(n,)``, hit ``(n,)``."""
        dr = self.dr
        ray = self._camera_rays(pix, jitter, wavelengths, differential=False)
        si = self.ms.ray_intersect(ray)
        valid = si.is_valid()
        bsdf = si.bsdf(ray)
        alb = bsdf.eval_diffuse_reflectance(si, valid)
        n = si.sh_frame.n
        return {"albedo": np.stack([np.asarray(alb[i]) for i in range(4)], axis=1),
                "normal": np.stack([np.asarray(n[i]) for i in range(3)], axis=1),
                "distance": np.asarray(dr.select(valid, si.t, 0.0)),
                "hit": np.asarray(valid, dtype=bool)}
