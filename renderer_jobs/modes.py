"""The renderer's option families by name: wavelength sampling, pixel samplers, backends and job executors.

:class:`retarget.registry.MethodRegistry` families (case-insensitive, one error naming the valid
choices), each name mapped to a one-line description. Pure Python, unlike the modules that implement
them (:mod:`renderer_jobs.mitsuba.render` loads Mitsuba's bindings and numpy, :mod:`renderer_jobs.jobs`
the scene model): the command line lists these choices in ``--help`` without importing either.
"""

from __future__ import annotations

from illumix.retarget.registry import MethodRegistry

# See renderer_jobs.mitsuba.render, "Wavelength sampling".
WAVELENGTH_MODES: MethodRegistry[str] = MethodRegistry("wavelength sampling", {
    "all-bands": "every path carries every band (default; renderer_jobs.mitsuba.bands), Mitsuba's render loop",
    "stratified": "4 wavelengths per path, illumix's numpy-driven paths; every band gets its exact share of each pixel's wavelength samples",
    "random": "as stratified but with Mitsuba's own wavelength sampling, four wavelengths drawn uniformly over the grid span",
})

# See renderer_jobs.jobs (module docstring).
EXECUTORS: MethodRegistry[str] = MethodRegistry("executor", {
    "local": "a process pool on this machine (--workers)",
    "ray": "one Ray task per job on the cluster at --address",
})

class BackendEntry(str):
    """A render backend's registry entry: its one-line description (what ``--help`` prints) and the
    module that implements :class:`renderer_jobs.backends.Backend` as ``BACKEND`` (imported on first
    use, so listing the choices imports no renderer)."""

    module: str

    def __new__(cls, description: str, module: str) -> BackendEntry:
        entry = super().__new__(cls, description)
        entry.module = module
        return entry


# The renderers that write transport cubes (renderer_jobs.backends). A new one: a module with a
# ``BACKEND`` and one entry here.
BACKENDS: MethodRegistry[str] = MethodRegistry("render backend", {
    "mitsuba": BackendEntry("Mitsuba 3 (default): every band on every path, quasi-random pixel samples",
                            "illumix.renderer_jobs.mitsuba.backend"),
    "cycles": BackendEntry("Blender Cycles, the thesis method: 3 fixed wavelengths per pass, 21 passes, the same seed",
                           "illumix.renderer_jobs.cycles.backend"),
}, aliases={"blender": "cycles"})

# Mitsuba's pixel samplers, for the "all-bands" mode (renderer_jobs.mitsuba.band_render).
SAMPLERS: MethodRegistry[str] = MethodRegistry("pixel sampler", {
    "multijitter": "correlated multi-jittered sampling (Kensler 2013); any spp",
    "ldsampler": "low-discrepancy (0,2)-sequences; spp a power of 2",
    "orthogonal": "orthogonal array sampling (Jarosz et al. 2019); spp a prime squared",
    "stratified": "jittered strata; any spp",
    "independent": "independent uniform samples (plain Monte Carlo); any spp",
}, aliases={"low-discrepancy": "ldsampler", "random": "independent"})
