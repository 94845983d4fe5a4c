"""The sun's light paths through the windows (issue 39).

A sun (Mitsuba's ``directional`` emitter) starts its light paths on a disk as wide as the whole scene
(``sample_emitter_ray``): in a room, nearly all of them end on the outside of its walls, and the few
through a window are too few to draw the rare paths that matter (room 9130's sun, seen from the next
room: 256 light paths per pixel came back with 46 % of what camera paths found). Yet that sunlit
patch on a floor is just what light paths are good at: a camera path must find it by a bounce, a
light path starts there (bench/SCENES.md, "A sun's light paths through the windows").

So the sun's light is split by the line it travels along. Every line parallel to the sun's direction
either crosses a window rectangle (the scene's sky portals, :func:`window_rects`) or crosses none.

- Lines through a window: light paths. A window is picked in proportion to its area projected across
  the sun's direction, a point uniform on it, and the ray started outside the scene on that line (so
  a window's frame or jamb is hit first where it is); weight ``E · A⊥ / k`` over Mitsuba's ``E · π R²``
  (``k`` the windows the line crosses: a line through two is drawn from either, counted once).
- Lines through no window — a sunlit wall outside, whose light may reflect in through a window; sun
  through an opening that is not a portal: camera paths, whose light sample of the sun counts only
  along such lines (:func:`renderer_jobs.mitsuba.bands.make_integrator`'s ``sun_rest``). Light paths
  would reach them only from Mitsuba's disk, rarely and with a heavy weight: room 9135's view gets
  5.8 % of its sunlight off the building's outside walls, which light paths drawn from the disk
  returned as one pixel in a few renders.

The two parts add up to the sun's whole contribution whatever the geometry; which rectangles are
windows decides only how well it works, never what it estimates.
"""

from __future__ import annotations

import numpy as np
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba


def window_rects(scene) -> np.ndarray | None:
    """``(K, 4, 3)`` float64 per portal rectangle of ``scene`` (the sky portals that fill windows):
    its centre, its two half-extent vectors (Mitsuba's rectangle is ``[-1, 1]²``) and its unit
    normal; None when there is none (other portal shapes are not windows this module draws from)."""
    out = []
    for s in scene.shapes:
        if not scene.is_portal(s) or s.type != "rectangle":
            continue
        m = s.transform.to_matrix() if s.transform is not None else np.eye(4)
        c, u, v = m[:3, 3], m[:3, 0], m[:3, 1]
        n = np.cross(u, v)
        if np.linalg.norm(n) > 0:
            out.append([c, u, v, n / np.linalg.norm(n)])
    return np.asarray(out, np.float64) if out else None


class SunWindows:
    """The windows on the Dr.Jit side, and the sun's lines drawn through them (module docstring)."""

    def __init__(self, rects: np.ndarray):
        self.rects = np.asarray(rects, np.float64)
        # a point's coordinates in a rectangle's (u, v), for rectangles that a transform has sheared
        self.dual = []
        for c, u, v, _ in self.rects:
            g = np.array([[u @ u, u @ v], [u @ v, v @ v]])
            self.dual.append(np.linalg.inv(g))
        self.area = [float(4 * np.linalg.norm(np.cross(u, v))) for _, u, v, _ in self.rects]
        self.vec = [[tuple(float(x) for x in row) for row in r] for r in self.rects]  # Dr.Jit takes floats

    @staticmethod
    def has_sun(ms) -> bool:
        """Whether the loaded scene (one emitter pass) holds a sun: other passes draw their light
        paths as Mitsuba does, with the same random numbers as in a room without windows."""
        mi, _ = import_mitsuba()
        return any(mi.has_flag(e.flags(), mi.EmitterFlags.Infinite) and mi.has_flag(e.flags(), mi.EmitterFlags.DeltaDirection)
                   for e in ms.emitters())

    def draw(self, mi, dr, ms, ray, weight, emitter, sampler):
        """``(ray, weight)``: Mitsuba's emitter ray and weight, with the lanes whose emitter is a sun
        drawn along a line through the windows (weight 0 where no window faces the sun: camera paths
        take all of it then)."""
        is_sun = mi.has_flag(emitter.flags(), mi.EmitterFlags.Infinite) & mi.has_flag(
            emitter.flags(), mi.EmitterFlags.DeltaDirection)
        d = ray.d  # on a sun's lanes, its direction of travel
        proj = [a * dr.abs(dr.dot(d, mi.Vector3f(*r[3]))) for a, r in zip(self.area, self.vec)]
        total = sum(proj[1:], proj[0])
        pick = sampler.next_1d() * total
        s2 = sampler.next_2d()
        c, u, v = mi.Point3f(*self.vec[0][0]), mi.Vector3f(*self.vec[0][1]), mi.Vector3f(*self.vec[0][2])
        acc = proj[0]
        for k in range(1, len(proj)):  # the window whose share of the projected area holds `pick`
            later = pick >= acc
            c = dr.select(later, mi.Point3f(*self.vec[k][0]), c)
            u = dr.select(later, mi.Vector3f(*self.vec[k][1]), u)
            v = dr.select(later, mi.Vector3f(*self.vec[k][2]), v)
            acc = acc + proj[k]
        p = c + (2.0 * s2.x - 1.0) * u + (2.0 * s2.y - 1.0) * v
        sphere = ms.bbox().bounding_sphere()
        radius = dr.dot(sphere.center - ray.o, d)  # the disk's radius: Mitsuba starts it that far back
        start = p - d * (dr.dot(p - sphere.center, d) + radius)  # outside the scene, on p's line
        k = self.crossings(mi, dr, start, d)
        w_sun = dr.select(total > 0.0, weight * (total / (dr.pi * dr.square(radius) * dr.maximum(k, 1.0))), 0.0)
        o = dr.select(is_sun, start, ray.o)
        return mi.Ray3f(o, d, ray.time, ray.wavelengths), dr.select(is_sun, w_sun, weight)

    def crossings(self, mi, dr, o, d):
        """How many window rectangles the line ``o + t·d`` (every t) crosses, per lane (a Float)."""
        count = mi.Float(0.0)
        for (c, u, v, n), g in zip(self.vec, self.dual):
            cosn = dr.dot(d, mi.Vector3f(*n))
            t = dr.dot(mi.Point3f(*c) - o, mi.Vector3f(*n)) / dr.select(cosn != 0.0, cosn, 1.0)
            r = o + t * d - mi.Point3f(*c)
            ru, rv = dr.dot(r, mi.Vector3f(*u)), dr.dot(r, mi.Vector3f(*v))
            a = float(g[0, 0]) * ru + float(g[0, 1]) * rv
            b = float(g[1, 0]) * ru + float(g[1, 1]) * rv
            count += dr.select((cosn != 0.0) & (dr.abs(a) <= 1.0) & (dr.abs(b) <= 1.0), 1.0, 0.0)
        return count
