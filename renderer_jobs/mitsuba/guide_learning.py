"""Learning a path guide (:mod:`renderer_jobs.mitsuba.path_guide`) for one loaded scene: short
training renders of the band integrator in record mode.

Training runs ``TRAINING_PATHS`` paths per pixel in iterations: the first samples the BSDFs only,
each later one is guided by the field learnt so far (so it explores where light was seen, as in
Müller et al. 2017), and the field is learnt from the records of every iteration (each is an
unbiased estimate of the bins' incident light, whatever pdf drew its bounces). Four bands spread
over the group's live bands stand for the spectrum: the guide only has to know where light comes
from. Paths start at the view's pixels (uniform jitter, an independent sampler), so the field
learns the places this view's paths reach.
"""

from __future__ import annotations

import time

import numpy as np

from illumix.renderer_jobs.mitsuba.bands import band_quadruples, make_integrator
from illumix.renderer_jobs.mitsuba.path_guide import N_SIDES, GuideArrays, GuideField, field_from_records, grid_for
from illumix.renderer_jobs.mitsuba.scene_dict import scene_bounds
from illumix.renderer_jobs.mitsuba.trace import camera_rays
from illumix.renderer_jobs.mitsuba.variant import import_mitsuba
from illumix.scene.model import Scene

TRAINING_PATHS = (8, 8, 16)  # paths per pixel of each training iteration
MAX_LANES = 1 << 20  # paths per traced batch (memory: a few floats per bounce slot each)


def learn_guide(scene: Scene, ms, sensor, live: np.ndarray, flat: bool, seed: int,
                iterations=TRAINING_PATHS) -> tuple[GuideField, dict]:
    """The field learnt for ``ms`` (a loaded Mitsuba scene) seen by ``sensor``, with the group's
    ``live`` bands (``flat``: emission evaluated once, as the render does), and what it cost."""
    mi, dr = import_mitsuba()
    t0 = time.perf_counter()
    lo, cell, dims = grid_for(*scene_bounds(scene))
    live = np.asarray(live, np.int64)
    quads, _ = band_quadruples(scene.spectral_grid.edges, live[np.linspace(0, live.size - 1, 4).round().astype(int)])
    field = field_from_records(lo, cell, dims, np.zeros(0, np.int64), np.zeros(0))  # nothing learnt yet
    index, value = [], []
    for it, n in enumerate(iterations):
        integrator = make_integrator(quads, scene.spectral_grid.step, scene.max_depth, False, flat,
                                     guide=GuideArrays(mi, dr, field), record=True)
        i, v = _records(mi, dr, integrator, ms, sensor, int(n), (seed * 7919 + it) & 0x7FFFFFFF)
        index.append(i)
        value.append(v)
        field = field_from_records(lo, cell, dims, np.concatenate(index), np.concatenate(value))
    n_rec = int(sum(int(np.count_nonzero(i >= 0)) for i in index))
    return field, {"learn_s": round(time.perf_counter() - t0, 4), "training_paths_per_pixel": int(sum(iterations)),
                   "records": n_rec, "voxels": int(np.prod(dims)),
                   "cells": int(np.prod(dims)) * N_SIDES, "guided_cells": field.guided_cells}


def _records(mi, dr, integrator, ms, sensor, paths: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(index, value)`` of every bounce record of ``paths`` training paths per pixel."""
    w, h = (int(x) for x in sensor.film().crop_size())
    pix = np.repeat(np.arange(w * h, dtype=np.int64), paths)
    rng = np.random.default_rng(seed)
    index, value = [], []
    for b, start in enumerate(range(0, pix.size, MAX_LANES)):
        p = pix[start:start + MAX_LANES]
        ray = camera_rays(mi, sensor, w, h, p, rng.random((p.size, 2), dtype=np.float32),
                          np.full((p.size, 4), 550.0, np.float32), differential=False)
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(dr.opaque(mi.UInt32, (seed + b) & 0xFFFFFFFF), p.size)
        idx, _, val = integrator.learn(ms, sampler, ray, mi.Bool(True))
        dr.eval(*idx, *val)
        index.append(np.concatenate([np.asarray(x, np.int64) for x in idx]))
        value.append(np.concatenate([np.asarray(x, np.float64) for x in val]))
    return np.concatenate(index), np.concatenate(value)
