"""Path guiding for light that only rare paths find (issue 39): a lamp in the next room, daylight
into a room without a window, a bulb inside its shade.

Where plain path tracing finds such light, it finds it by chance: a BSDF-sampled bounce that
happens to leave through the doorway, then a light sample that reaches the lamp. This module
learns, from a short training render, *where light arrives from* at every place in the scene, and
the band integrator (:mod:`renderer_jobs.mitsuba.bands`) then samples some bounces from that:

- **The field** (:class:`GuideField`): a uniform voxel grid over the scene's bounds (at most
  ``GRID_MAX`` cells along its longest side), each voxel split in ``N_SIDES`` by the axis its
  surface faces (±x, ±y, ±z of the normal on the path's side: a room's floor, ceiling and walls
  learn apart even where one voxel holds a corner) × ``NZ·NPHI`` equal-area direction bins of the
  whole sphere (uniform in ``cos θ`` and ``φ``, world frame). Per cell, a discrete distribution over
  the bins, ∝ the estimated incident radiance ``∫_bin L_in dω`` (a plain version of Müller et al.,
  "Practical Path Guiding for Efficient Light-Transport Simulation", EGSR 2017: a fixed grid for
  their SD-tree).
- **Learning** (:func:`field_from_records`): training paths record at each bounce its cell, its
  direction's bin and ``L_in / pdf`` — the radiance that came back along that bounce from every later
  vertex (light samples and emitters hit, MIS-weighted as they count in the render), divided by the
  throughput to there and the direction's pdf. The mean per cell estimates each bin's integral.
  Light samples of the bounce's own vertex are not in it: what next-event estimation already finds
  needs no guiding.
- **Sampling**: at a vertex whose BSDF has no delta lobe and whose cell learnt something, the
  direction comes from the guide with probability ``ALPHA``, else from the BSDF (one-sample MIS: the
  weight is ``f·cos / (α p_guide + (1−α) p_bsdf)`` either way, and the same mixture pdf enters the
  MIS weights against light samples). So the estimate stays unbiased whatever the guide learnt, and
  the guide can only move paths to where light was seen.

The renderer uses it in the until-clean rule's rounds from the third on
(:mod:`renderer_jobs.mitsuba.until_clean`): a cube clean by twice its spp never pays for it. At equal
paths a guided render costs about 1.4× a plain one (training included) and pays only where light
comes by bounces; ``bench/SCENES.md`` ("Path guiding") measures it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NZ, NPHI = 8, 16  # direction bins: 8 in cos θ × 16 in φ = 128 bins of 4π/128 sr each
N_BINS = NZ * NPHI
N_SIDES = 6  # cells per voxel: the axis (±x, ±y, ±z) the surface's normal is closest to
GRID_MAX = 16  # voxels along the scene's longest side (a room of 8 m: 0.5 m cells)
ALPHA = 0.5  # share of guided bounces where the guide applies
MIN_RECORDS = 64  # a cell with fewer training bounces keeps to BSDF sampling
UNIFORM_SHARE = 0.05  # every bin keeps this share of a uniform distribution: no bin is starved


@dataclass
class GuideField:
    """The learnt distribution: ``pmf (C, N_BINS)`` per cell (rows sum to 1; ``C`` = voxels ×
    ``N_SIDES``), ``alpha (C,)`` (the guided share, 0 where the cell learnt nothing), over a grid of
    ``dims (3,)`` voxels from ``lo`` of ``cell (3,)`` metres."""
    lo: np.ndarray
    cell: np.ndarray
    dims: np.ndarray
    pmf: np.ndarray
    alpha: np.ndarray

    @property
    def guided_cells(self) -> int:
        return int(np.count_nonzero(self.alpha))


def grid_for(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(lo, cell, dims)`` of the voxel grid over the bounds ``lo…hi`` (metres), padded by 1 %:
    cubic cells, ``GRID_MAX`` along the longest side."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    pad = 0.01 * max(float(np.max(hi - lo)), 1e-3)
    lo, hi = lo - pad, hi + pad
    size = float(np.max(hi - lo)) / GRID_MAX
    dims = np.clip(np.ceil((hi - lo) / size), 1, GRID_MAX).astype(np.int64)
    return lo, np.full(3, size), dims


def field_from_records(lo, cell, dims, index: np.ndarray, value: np.ndarray) -> GuideField:
    """The field learnt from training bounces: ``index`` = cell · N_BINS + bin of each bounce
    (negative: no record), ``value`` its ``L_in / pdf`` (module docstring). Per cell the bins'
    means estimate ``∫_bin L_in dω``; a cell guides where it had ``MIN_RECORDS`` bounces and saw light."""
    n_vox = int(np.prod(dims)) * N_SIDES
    ok = (index >= 0) & np.isfinite(value) & (value >= 0)
    index, value = index[ok].astype(np.int64), value[ok].astype(np.float64)
    sums = np.bincount(index, weights=value, minlength=n_vox * N_BINS).reshape(n_vox, N_BINS)
    counts = np.bincount(index // N_BINS, minlength=n_vox)
    total = sums.sum(axis=1)
    learnt = (counts >= MIN_RECORDS) & (total > 0)
    pmf = np.full((n_vox, N_BINS), 1.0 / N_BINS)
    pmf[learnt] = ((1 - UNIFORM_SHARE) * sums[learnt] / total[learnt, None] + UNIFORM_SHARE / N_BINS)
    alpha = np.where(learnt, ALPHA, 0.0)
    return GuideField(np.asarray(lo, np.float64), np.asarray(cell, np.float64), np.asarray(dims, np.int64),
                      pmf.astype(np.float32), alpha.astype(np.float32))


class GuideArrays:
    """The field on the Dr.Jit side: every value an opaque input (one compiled kernel for any field)."""

    def __init__(self, mi, dr, field: GuideField) -> None:
        self.mi, self.dr = mi, dr
        self.lo = mi.Vector3f(*[float(x) for x in field.lo])
        self.inv_cell = mi.Vector3f(*[float(1.0 / x) for x in field.cell])
        self.dims = mi.Vector3i(*[int(x) for x in field.dims])
        self.pmf = mi.Float(np.ascontiguousarray(field.pmf.ravel(), np.float32))
        self.cdf = mi.Float(np.ascontiguousarray(np.cumsum(field.pmf, axis=1, dtype=np.float64).ravel(), np.float32))
        self.alpha = mi.Float(np.ascontiguousarray(field.alpha, np.float32))
        dr.make_opaque(self.lo, self.inv_cell, self.dims)

    def voxel(self, si):
        """Cell index (UInt32) of surface interactions ``si``: the voxel of ``si.p`` (clamped into the
        grid) and the axis its normal faces on the side the path arrived from."""
        mi, dr = self.mi, self.dr
        c = mi.Vector3i(dr.floor((si.p - self.lo) * self.inv_cell))
        c = dr.clip(c, 0, self.dims - 1)
        n = si.n * dr.sign(dr.dot(si.n, si.to_world(si.wi)))
        a = dr.abs(n)
        axis = dr.select((a.x >= a.y) & (a.x >= a.z), 0, dr.select(a.y >= a.z, 1, 2))
        neg = dr.select(axis == 0, n.x, dr.select(axis == 1, n.y, n.z)) < 0
        side = mi.UInt32(2 * axis + dr.select(neg, 1, 0))
        return mi.UInt32((c.x * self.dims.y + c.y) * self.dims.z + c.z) * N_SIDES + side

    def alpha_at(self, voxel, active):
        return self.dr.gather(self.mi.Float, self.alpha, voxel, active)

    def bin_of(self, d):
        """Direction bin (UInt32) of world unit directions ``d``."""
        mi, dr = self.mi, self.dr
        iz = dr.clip(mi.Int32(dr.floor((d.z + 1.0) * (0.5 * NZ))), 0, NZ - 1)
        phi = dr.atan2(d.y, d.x)  # (−π, π]
        ip = dr.clip(mi.Int32(dr.floor((phi + dr.pi) * (NPHI / (2 * dr.pi)))), 0, NPHI - 1)
        return mi.UInt32(iz * NPHI + ip)

    def pdf(self, voxel, d, active):
        """Solid-angle pdf of the guide at ``voxel`` for world directions ``d``."""
        mi, dr = self.mi, self.dr
        return dr.gather(mi.Float, self.pmf, voxel * N_BINS + self.bin_of(d), active) * (N_BINS / (4 * dr.pi))

    def sample(self, voxel, u: float, u2, active):
        """World directions drawn from the guide at ``voxel`` (``u`` picks the bin by a binary search
        of the voxel's CDF, ``u2`` the point in it, uniform in solid angle) and their pdf."""
        mi, dr = self.mi, self.dr
        base = voxel * N_BINS
        k = mi.UInt32(0)
        step = N_BINS // 2
        while step >= 1:  # the first bin whose CDF exceeds u
            below = dr.gather(mi.Float, self.cdf, base + k + step - 1, active) <= u
            k = dr.select(below, k + step, k)
            step //= 2
        k = dr.minimum(k, N_BINS - 1)
        iz, ip = k // NPHI, k % NPHI
        z = dr.clip(-1.0 + 2.0 * (mi.Float(iz) + u2.x) / NZ, -1.0, 1.0)
        phi = -dr.pi + 2 * dr.pi * (mi.Float(ip) + u2.y) / NPHI
        r = dr.safe_sqrt(1.0 - z * z)
        s, c = dr.sincos(phi)
        d = mi.Vector3f(r * c, r * s, z)
        # the pdf of the bin d falls in, as pdf() gives it everywhere else (rounding at a bin's edge
        # may name the neighbour: one value for a direction, however it was reached)
        return d, self.pdf(voxel, d, active)


class GuidedBounce:
    """One vertex's bounce drawn from the guide/BSDF mixture (module docstring), for the band
    integrator's loop: made before its per-quadruple loop, asked for each quadruple's weight
    (:meth:`weight`) and the light sample's MIS pdf (:meth:`mixture_pdf_em`), then told the BSDF's
    own sample to overwrite with the direction taken (:meth:`chosen`). ``active``: lanes that
    bounce and are not white surfaces (those keep cosine sampling). Every BSDF without a delta
    lobe is guided: diffuse, rough plastic, rough metal (measured: guiding the diffuse ones only,
    which needs no BSDF call per quadruple, left 9131's desk lamp 1.5× noisier in variance)."""

    def __init__(self, mi, dr, g: GuideArrays, sampler, si, bsdf, ctx, flags, active, d_em, em_on) -> None:
        self.mi, self.dr, self.g, self.si, self.bsdf, self.ctx = mi, dr, g, si, bsdf, ctx
        self.vox = g.voxel(si)
        guidable = active & si.is_valid() & ~mi.has_flag(flags, mi.BSDFFlags.Delta)
        self.a = dr.select(guidable, g.alpha_at(self.vox, guidable), 0.0)
        self.on = self.a > 0.0
        u_pick, u_bin, u_in = sampler.next_1d(active), sampler.next_1d(active), sampler.next_2d(active)
        self.use = self.on & (u_pick < self.a)
        d, pdf_g = g.sample(self.vox, u_bin, u_in, self.use)
        self.wo = si.to_local(d)
        self.mix = self.a * pdf_g + (1.0 - self.a) * bsdf.pdf(ctx, si, self.wo, self.use)
        self.pdf_em = g.pdf(self.vox, d_em, em_on & self.on)
        self.mix_bs = None

    def weight(self, bs, w_bsdf):
        """This quadruple's throughput weight ``f·cos / mixture pdf`` of the direction taken
        (``w_bsdf``: the BSDF sample's own ``f·cos / p_bsdf``), at the wavelengths ``si`` carries now."""
        dr = self.dr
        if self.mix_bs is None:  # the BSDF's direction is the same at every quadruple
            pdf_g = self.g.pdf(self.vox, self.si.to_world(bs.wo), self.on)
            self.mix_bs = self.a * pdf_g + (1.0 - self.a) * bs.pdf
        f = self.bsdf.eval(self.ctx, self.si, self.wo, self.use)  # with the cosine, as Mitsuba's eval
        from_bsdf = dr.select(self.on & (self.mix_bs > 0), w_bsdf * bs.pdf / self.mix_bs, w_bsdf)
        return dr.select(self.use, f / self.mix, from_bsdf)

    def mixture_pdf_em(self, pdf_bsdf):
        """The pdf with which a bounce would have found the light sample's direction."""
        return self.a * self.pdf_em + (1.0 - self.a) * pdf_bsdf

    def chosen(self, bs) -> None:
        """``bs`` (the BSDF's sample) becomes the direction taken, with its mixture pdf."""
        mi, dr = self.mi, self.dr
        bs.wo = dr.select(self.use, self.wo, bs.wo)
        bs.pdf = dr.select(self.use, self.mix, dr.select(self.on, self.mix_bs, bs.pdf))
        bs.sampled_type = dr.select(self.use, mi.UInt32(+mi.BSDFFlags.DiffuseReflection), bs.sampled_type)
        bs.eta = dr.select(self.use, 1.0, bs.eta)


def light_of(dr, L) -> object:
    """A path's radiance summed over its quadruples' lanes (what the training records weigh)."""
    total = dr.sum(L[0])
    for spec in L[1:]:
        total += dr.sum(spec)
    return total


def empty_records(mi, max_depth: int) -> tuple:
    """Loop state of a training path: per bounce slot (``max_depth − 1``: the last vertex does not
    bounce) its record index (−1: none), ``1 / (throughput · pdf)`` and the light gathered after it."""
    slots = max(0, max_depth - 1)
    return ([mi.Int32(-1) for _ in range(slots)], [mi.Float(0.0) for _ in range(slots)],
            [mi.Float(0.0) for _ in range(slots)])


def add_record(mi, dr, g: GuideArrays, rec: tuple, depth, light, si, d, pdf, valid, beta) -> None:
    """In place: ``light`` (what this vertex added to the path) goes to every earlier bounce's record,
    divided by that bounce's throughput and pdf (so each holds ``L_in / pdf``); then the bounce leaving
    this vertex (world direction ``d``, pdf ``pdf``, throughput after it ``beta``) takes its slot."""
    index, inv, value = rec
    for s in range(len(index)):
        value[s] = dr.select(depth > s, value[s] + light * inv[s], value[s])
    mean_beta = light_of(dr, beta) / (4 * len(beta))
    scale = mean_beta * pdf
    ok = valid & (scale > 0) & dr.isfinite(scale)
    new = mi.Int32(g.voxel(si) * N_BINS + g.bin_of(d))
    for s in range(len(index)):
        here = ok & (depth == s)
        index[s] = dr.select(here, new, index[s])
        inv[s] = dr.select(here, 1.0 / scale, inv[s])
