"""Rays in, radiance out: Mitsuba's integrator driven on rays and wavelengths chosen by the caller.

:class:`Tracer` loads one (view, set of light groups) once (:func:`renderer_jobs.mitsuba.scene_dict.
load_mitsuba_scene`) and traces batches of paths: pixel index, sub-pixel jitter and the four
wavelengths of each path come from numpy, the radiance goes back to numpy. This is what lets
:mod:`renderer_jobs.mitsuba.render` choose every wavelength (stratified bands) instead of Mitsuba's film.

Illumination (DESIGN.md "Physical GT"): the radiance ``U`` a *white Lambertian* surface at the path's
first hit would send back to the camera, bounces included (``U = E/π`` with ``E`` the irradiance
there). :meth:`Tracer.trace` can also return, from the same kernel, the first hit's diffuse
reflectance and whether its BSDF is purely diffuse: there every contribution of the path carries
the factor ``ρ(λ)`` (BSDF ``ρ/π``, cosine sampling weight ``ρ``), so ``L/ρ`` is an unbiased sample of
``U`` at no extra tracing. Elsewhere (glossy, metal, glass, black or emitting first hits)
:meth:`Tracer.white_lambertian` traces it: next-event estimation at the first hit with BSDF ``1/π``,
plus one cosine-sampled continuation whose own first emission is removed (the light sampling
already counts direct light).
"""

from __future__ import annotations

import numpy as np

from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba
from illumix.scene.model import Scene


def _numpy4(spec) -> np.ndarray:
    """A 4-wavelength Dr.Jit spectrum as ``(n, 4)`` float32."""
    return np.stack([np.asarray(spec[i], dtype=np.float32) for i in range(4)], axis=1)


def _aligned(a: np.ndarray) -> np.ndarray:
    """A 64-byte aligned contiguous float32 copy: Dr.Jit emits different (uncached) kernels for
    differently aligned input buffers, so every input gets the same alignment."""
    a = np.asarray(a, dtype=np.float32).ravel()
    buf = np.empty(a.size + 16, dtype=np.float32)
    k = (-buf.ctypes.data % 64) // 4
    out = buf[k:k + a.size]
    out[...] = a
    return out


def camera_rays(mi, sensor, width: int, height: int, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray,
                differential: bool):
    """Camera rays of ``sensor`` through film position ``pixel + jitter`` (``pix``: flat row-major
    indices of a ``width``×``height`` film, ``jitter (n, 2)`` in pixels) carrying the 4 given wavelengths."""
    px = (pix % width).astype(np.float32) + jitter[:, 0]
    py = (pix // width).astype(np.float32) + jitter[:, 1]
    pos = mi.Point2f(mi.Float(_aligned(px / width)), mi.Float(_aligned(py / height)))
    sample = sensor.sample_ray_differential if differential else sensor.sample_ray
    ray, _ = sample(0.0, mi.Float(0.5), pos, mi.Point2f(0.5, 0.5))
    ray.wavelengths = type(ray.wavelengths)(*[mi.Float(_aligned(wavelengths[:, i])) for i in range(4)])
    return ray


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
        self._cont = None

    def trace(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, seed: int,
              first_hit: bool = False):
        """Radiance ``(n, 4)`` float32 of paths through pixels ``pix`` (flat index, row-major from the
        top-left) at sub-pixel offsets ``jitter (n, 2)`` carrying ``wavelengths (n, 4)`` nm.

        ``first_hit``: also return, computed in the same kernel, the first hit's diffuse reflectance
        ``(n, 4)`` at the path's wavelengths, whether its BSDF is purely diffuse and not emitting
        ``(n,)`` (so ``L/ρ`` samples the illumination, module docstring) and whether it hit ``(n,)``.
        """
        mi, dr = self.mi, self.dr
        n = len(pix)
        sampler = self.sensor.sampler().clone()
        sampler.seed(dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), n)
        ray = self._camera_rays(pix, jitter, wavelengths, differential=True)
        spec, valid, _ = self.integrator.sample(self.ms, sampler, ray, None, True)
        spec = mi.unpolarized_spectrum(spec)
        if not first_hit:
            dr.eval(spec)
            return _numpy4(spec)
        si = self.ms.ray_intersect(mi.Ray3f(ray))
        hit = si.is_valid()
        bsdf = si.bsdf()
        albedo = bsdf.eval_diffuse_reflectance(si, hit)
        flags = bsdf.flags()
        diffuse = hit & mi.has_flag(flags, mi.BSDFFlags.DiffuseReflection)
        for other in (mi.BSDFFlags.Glossy, mi.BSDFFlags.Delta, mi.BSDFFlags.Transmission):
            diffuse &= ~mi.has_flag(flags, other)
        diffuse &= ~si.shape.is_emitter()
        dr.eval(spec, albedo, diffuse, hit)
        return (_numpy4(spec), _numpy4(albedo), np.asarray(diffuse, dtype=bool), np.asarray(hit, dtype=bool))

    def white_lambertian(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, seed: int
                         ) -> np.ndarray:
        """Illumination samples ``(n, 4)`` float32: the radiance a white Lambertian surface at each
        path's first hit would send back along the camera ray (module docstring); 0 where nothing
        is hit. The continuation traces at most ``max_depth − 1`` more bounces, as the camera path."""
        mi, dr = self.mi, self.dr
        n = len(pix)
        if self.scene.max_depth <= 1:  # camera paths carry no reflected light: neither does U
            return np.zeros((n, 4), np.float32)
        sampler = self.sensor.sampler().clone()
        sampler.seed(dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), n)
        ray = self._camera_rays(pix, jitter, wavelengths, differential=False)
        si = self.ms.ray_intersect(ray)
        hit = si.is_valid()
        normal = si.sh_frame.n
        normal = dr.select(dr.dot(normal, -ray.d) < 0, -normal, normal)  # the side the camera sees
        ds, weight = self.ms.sample_emitter_direction(si, sampler.next_2d(hit), True, hit)
        direct = weight * dr.maximum(dr.dot(normal, ds.d), 0.0) / dr.pi
        d = mi.Frame3f(normal).to_world(mi.warp.square_to_cosine_hemisphere(sampler.next_2d(hit)))
        bounce = si.spawn_ray(d)
        si2 = self.ms.ray_intersect(bounce, hit)
        emitted = si2.emitter(self.ms, hit).eval(si2, hit)  # counted by the light sample above
        scattered, _, _ = self._continuation().sample(self.ms, sampler, bounce, None, hit)
        u = mi.unpolarized_spectrum(dr.select(hit, direct + scattered - emitted, 0.0))
        dr.eval(u)
        return _numpy4(u)

    def spectral_albedo(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray) -> np.ndarray:
        """Diffuse reflectance ``(n, len(wavelengths))`` float32 of each camera ray's first hit at
        every one of ``wavelengths`` (nm, e.g. the band centres; step spectra are exact there):
        one intersection, then Mitsuba's ``eval_diffuse_reflectance`` four wavelengths at a time.
        0 where nothing is hit and for BSDFs with no diffuse lobe (metal, glass): Mitsuba's
        ``roughconductor`` answers ``eval_diffuse_reflectance`` with a view-dependent value (up to
        2.7 on a silver mirror), so the lobe is read from the BSDF's flags."""
        mi, dr = self.mi, self.dr
        lam = np.asarray(wavelengths, np.float64)
        quads = np.concatenate([lam, np.repeat(lam[-1:], -len(lam) % 4)]).reshape(-1, 4)
        ray = self._camera_rays(pix, jitter, np.tile(quads[0].astype(np.float32), (len(pix), 1)), False)
        si = self.ms.ray_intersect(ray)
        bsdf = si.bsdf(ray)
        hit = si.is_valid() & mi.has_flag(bsdf.flags(), mi.BSDFFlags.DiffuseReflection)
        out = np.empty((len(pix), quads.size), np.float32)
        for q, quad in enumerate(quads):
            wl = type(si.wavelengths)(*[float(x) for x in quad])
            dr.make_opaque(wl)  # an input, not literals: the 16 quadruples share one kernel
            si.wavelengths = wl
            alb = dr.select(hit, bsdf.eval_diffuse_reflectance(si, hit), 0.0)
            dr.eval(alb)
            out[:, 4 * q:4 * q + 4] = _numpy4(alb)
        return out[:, :len(lam)]

    def direct_irradiance(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, seed: int,
                          behind_dielectric: bool = False, seen: bool = False):
        """One next-event sample per ray of the *direct* light a white Lambertian surface at the
        first hit sends back, ``(n, 4)`` float32 (``E_direct/π``, the direct part of
        :meth:`white_lambertian`): light sampling with visibility, no bounce. 0 where nothing is hit
        and on emitting surfaces. Shadows and lit patches have sharp, noise-free edges in its mean
        over a few dozen samples: the illumination-edge guide of :mod:`retarget.denoise`.

        ``behind_dielectric``: also ``behind (n, 4)``, the same sample where only surfaces that
        transmit (glass) block its shadow ray, else 0 (:meth:`_blocked_by_dielectrics_only`).
        ``seen``: also the same sample's light as the camera sees it, through the surface's own
        BSDF (a glossy highlight included), ``(n, 4)``, and the surface's diffuse reflectance
        ``(n, 4)``. Returns the image alone, or a tuple: ``(direct[, behind][, seen, albedo])``."""
        mi, dr = self.mi, self.dr
        n = len(pix)
        sampler = self.sensor.sampler().clone()
        sampler.seed(dr.opaque(mi.UInt32, seed & 0xFFFFFFFF), n)
        ray = self._camera_rays(pix, jitter, wavelengths, differential=False)
        si = self.ms.ray_intersect(ray)
        hit = si.is_valid() & ~si.shape.is_emitter()
        normal = si.sh_frame.n
        normal = dr.select(dr.dot(normal, -ray.d) < 0, -normal, normal)  # the side the camera sees
        # without behind_dielectric, Mitsuba's own shadow test (the guide as it always was)
        ds, weight = self.ms.sample_emitter_direction(si, sampler.next_2d(hit), not behind_dielectric, hit)
        u = mi.unpolarized_spectrum(dr.select(hit, weight * dr.maximum(dr.dot(normal, ds.d), 0.0) / dr.pi, 0.0))
        out, visible = [u], hit
        if behind_dielectric:
            shadow = si.spawn_ray_to(ds.p)
            visible = hit & (ds.pdf != 0) & ~self.ms.ray_test(shadow, hit)
            glass = self._blocked_by_dielectrics_only(shadow, ds.p, hit & ~visible)
            out = [dr.select(visible, u, 0.0), dr.select(glass, u, 0.0)]
        if seen:
            bsdf = si.bsdf(ray)
            f = mi.unpolarized_spectrum(bsdf.eval(mi.BSDFContext(), si, si.to_local(ds.d), hit))
            diffuse = hit & mi.has_flag(bsdf.flags(), mi.BSDFFlags.DiffuseReflection)  # as spectral_albedo
            out += [dr.select(visible, weight * f, 0.0), dr.select(diffuse, bsdf.eval_diffuse_reflectance(si, hit), 0.0)]
        dr.eval(*out)
        arrays = [_numpy4(a) for a in out]
        return arrays[0] if len(arrays) == 1 else tuple(arrays)

    def _blocked_by_dielectrics_only(self, shadow, target, active, max_crossings: int = 4):
        """Mask of the shadow rays in ``active`` (the blocked ones) whose every blocker before
        ``target`` transmits light (glass, a dielectric): followed straight through up to
        ``max_crossings`` surfaces (a sphere is two); an opaque blocker, or more crossings, is a
        plain shadow. Straight, so not where the glass focuses the light: only where it may."""
        mi = self.mi
        ok, pending, ray = mi.Bool(active), mi.Bool(active), shadow
        for _ in range(max_crossings):
            si = self.ms.ray_intersect(ray, pending)
            hit = pending & si.is_valid()
            transmits = mi.has_flag(si.bsdf().flags(), mi.BSDFFlags.Transmission)
            ok &= ~(hit & ~transmits)
            pending = hit & transmits
            ray = si.spawn_ray_to(target)
        return ok & ~pending

    def _continuation(self):
        if self._cont is None:
            depth = self.scene.max_depth
            self._cont = self.mi.load_dict({"type": "path", "max_depth": depth - 1})
        return self._cont

    def _camera_rays(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray, differential: bool):
        return camera_rays(self.mi, self.sensor, self.width, self.height, pix, jitter, wavelengths, differential)

    def first_hit(self, pix: np.ndarray, jitter: np.ndarray, wavelengths: np.ndarray,
                  rays: bool = False) -> dict[str, np.ndarray]:
        """Primary-hit AOVs per sample: albedo ``(n, 4)``, normal ``(n, 3)``, distance ``(n,)``, hit
        ``(n,)``, emitter ``(n,)`` (the hit shape emits, in the groups this tracer loaded); with
        ``rays``, also the camera rays' ``origin`` and unit ``direction`` ``(n, 3)``."""
        dr = self.dr
        ray = self._camera_rays(pix, jitter, wavelengths, differential=False)
        si = self.ms.ray_intersect(ray)
        valid = si.is_valid()
        bsdf = si.bsdf(ray)
        alb = bsdf.eval_diffuse_reflectance(si, valid)
        n = si.sh_frame.n
        out = {"albedo": np.stack([np.asarray(alb[i]) for i in range(4)], axis=1),
               "normal": np.stack([np.asarray(n[i]) for i in range(3)], axis=1),
               "distance": np.asarray(dr.select(valid, si.t, 0.0)),
               "hit": np.asarray(valid, dtype=bool),
               "emitter": np.asarray(valid & si.shape.is_emitter(), dtype=bool)}
        if rays:
            out["origin"] = np.stack([np.asarray(ray.o[i]) for i in range(3)], axis=1)
            out["direction"] = np.stack([np.asarray(ray.d[i]) for i in range(3)], axis=1)
        return out
