"""The renderer's option families by name: wavelength sampling and job executors.

:class:`retarget.registry.MethodRegistry` families (case-insensitive, one error naming the valid
choices), each name mapped to a one-line description. Pure Python, unlike the modules that implement
them (:mod:`renderer_jobs.mitsuba_render` loads Mitsuba's bindings and numpy, :mod:`renderer_jobs.jobs`
the scene model): the command line lists these choices in ``--help`` without importing either.
"""

from __future__ import annotations

from retarget.registry import MethodRegistry

# See renderer_jobs.mitsuba_render, "Wavelength sampling".
WAVELENGTH_MODES: MethodRegistry[str] = MethodRegistry("wavelength sampling", {
    "stratified": "every band gets its exact share of each pixel's wavelength samples",
    "random": "Mitsuba's own sampling, four wavelengths drawn uniformly over the grid span",
})

# See renderer_jobs.jobs (module docstring).
EXECUTORS: MethodRegistry[str] = MethodRegistry("executor", {
    "local": "a process pool on this machine (--workers)",
    "ray": "one Ray task per job on the cluster at --address",
})

# See renderer_jobs.backends: the renderers that write transport cubes.
BACKENDS: MethodRegistry[str] = MethodRegistry("render backend", {
    "mitsuba": "Mitsuba 3 (default): 4 stratified wavelengths per path, illumix's own sampling",
    "cycles": "Blender Cycles, the thesis method: 3 fixed wavelengths per pass, 21 passes, the same seed",
}, aliases={"blender": "cycles"})
