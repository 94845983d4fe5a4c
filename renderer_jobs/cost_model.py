"""What a render plan will cost before it runs: CPU seconds and wall time for the chosen workers,
from measured per-path costs (``illumix render --dry-run`` / ``illumix dataset --dry-run``, and the
weights of the progress lines' ETA, :class:`illumix.progress.ProgressLines`).

An *estimate*: scenes differ (light that is hard to reach costs more per path, a cube whose group
lights nothing is probed and skipped), and so do machines. The model, per job, in CPU seconds:

- a view job (metadata and AOVs): ``VIEW_S + VIEW_PER_PIXEL_S · pixels · aov_spp / 16``;
- a cube job: ``CUBE_S + CUBE_PER_PIXEL_S · pixels + PER_MPATH_S · paths / 1e6``, with
  ``paths = pixels · spp · (1 + boost)``, ``boost`` the targeted extra paths' share
  (:func:`boost_extra`: ``(boost_factor − 1)`` × the share of pixels boosted, which falls with the
  resolution); the illumination cube and the denoised copies are included (the defaults make them);
  where the until-clean rule applies (generated rooms by default), ``paths`` × :data:`CLEAN_PATHS_FACTOR`
  (at most ``clean_max_spp / spp``): what the rule averaged, not what one noisy cube can take;
- once per worker process: building the kernels, ``KERNEL_BUILD_S`` per light group kind (counted
  as distinct group names, at most ``MAX_KINDS``) when Dr.Jit's kernel cache (``~/.drjit``) is cold,
  as on a fresh machine or Ray worker image; a warm cache makes it a few seconds.

Wall time: the CPU seconds spread over the workers (each at most the machine's cores / workers
threads, ``WALL_PER_CPU`` of a CPU second each), the kernel builds counted on every worker.

**How the table was measured** (issue 38, 2026-11): :func:`renderer_jobs.execute.execute` on plans of
:func:`scene.demo.demo_room` ``(0)`` at each size (``jobs.apply_resolution``), the boost's share from each
cube's ``render_stats.targeted_paths``; default settings (all-bands, 16 bands per path,
multijitter, illumination cubes, dt-irradiance denoising with the 8× boost), one process
(``workers 1``), per-job ``cpu_s`` (``time.process_time``) from the job summaries, on the project's
CPU-only VM: **2 vCPUs shared with other jobs, Python 3.11, Mitsuba 3.9.1 / Dr.Jit 1.5.0 (LLVM)**.
Warm cubes (kernels cached): 64×48 × 16 spp 1.5–3.3 CPU s; 160×120 × 16 spp 7.5–14.1 s, × 64 spp
4.9–12.2 s, × 128 spp 12.7–21.7 s; 320×240 × 32 spp 18.1–38.0 s (``MEASURED``). Views: 0.6 s (64×48), 3.0 s
(160×120), 12.2 s (320×240). A fresh process with a cold kernel cache: the 64×48 demo (2 views, 6
cubes) took 32.6 CPU s against 16.4 s warm, the first cube of each of its 3 light groups 3.6–7.9 s
over a warm one (16 s in all); since the band sets' wavelengths are kernel inputs rather than
literals (one kernel for every band set), 27.2 against 17.9 s warm: 9.3 s of kernel builds for its
3 light group kinds (``bench/fixed_costs.py``, bench/RENDER_PERF.md). The per-cube terms were then
refitted to the demo measured warm at two sizes (the estimate had missed a fixed cost that small
cubes feel: 9.8 s estimated against 17.9 s measured at 64×48, 46.7 against 48.2 s at 160×120 × 16 spp):
``CUBE_S`` 0.3 → 1.9 s, ``CUBE_PER_PIXEL_S`` 2.6e-4 → 1.9e-4 s. On a scene it was not fitted on — a
generated room (generator 3, seed 8102, ~100 shapes), view and ``ceiling`` cube at 240×180 × 64 spp — it
estimates 32 CPU s against 52–58 s measured: a room's cube costs more per path than the demo's,
so generated rooms' jobs are counted at ``GENERATED_COST_FACTOR`` × (fitted on whole renders of two rooms,
checked on three more: 1.8–2.7 measured); other furnished scenes may cost as much. Timings of identical work move by ±15 % on that machine.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

#: the machine the table was measured on (printed with every estimate)
MACHINE = "a 2-vCPU shared VM (CPU only, Mitsuba 3.9 LLVM)"
VIEW_S = 0.15  # CPU s of a view job, fixed
VIEW_PER_PIXEL_S = 1.6e-4  # … per pixel at aov_spp 16
CUBE_S = 1.9  # CPU s of a cube job, fixed (refitted 2026-11-28 on the demo at 64×48 and 160×120, below)
CUBE_PER_PIXEL_S = 1.9e-4  # … per pixel (guides, boost mask, denoising, writing the cubes)
PER_MPATH_S = 3.2  # CPU s per million paths (each up to 16 bands; the illumination cube included)
KERNEL_BUILD_S = 3.1  # CPU s per light group kind, once per worker process, cold kernel cache
MAX_KINDS = 4
#: the until-clean rule's CPU per cube over a plain render's (spp 64, cap 1024, light and guided paths from the
#: third round) on 28 cubes of 10 generated rooms it was not calibrated on (bench/fireflies.py --clean-max-spp
#: default: about 592 against 183.9 CPU s with light paths — their daylight cubes, which take none, as the guided
#: rule's run rendered them —, 3.2x, as before light paths); counted as that many times the paths
CLEAN_PATHS_FACTOR = 3.2
#: a generated room's jobs cost this many times the demo's per pixel and path: whole `illumix render --views
#: view0 --clean-max-spp 0` runs (process CPU less ~8 s of start-up) against the estimate, fitted on rooms 7
#: and 8 at 160×120 (2.55, 2.43); checked on rooms 9 and 10 at 160×120 and room 7 at 240×180: 1.8, 2.7, 2.1
GENERATED_COST_FACTOR = 2.5
WALL_PER_CPU = 0.75  # wall s per CPU s of a worker with >= 2 threads (measured 0.68-0.9; 1 thread: 1)
#: the share of pixels the boost targets, measured at (pixels, share): it falls with the resolution
BOOST_SHARE = ((3072, 0.146), (19200, 0.064), (76800, 0.034))
#: measured warm cube CPU s, (width, height, spp) → (daylight, ceiling, desk) of the demo's front view
#: (CUBE_PER_PIXEL_S and PER_MPATH_S: a non-negative least-squares fit to the group means below with
#: CUBE_S fixed; fitted 1.4, 6.6, 10.9, 16.5, 29.7 s against measured 2.5, 11.4, 8.4, 17.9, 28.7 s)
MEASURED = {(64, 48, 16): (2.96, 2.98, 1.52), (160, 120, 16): (12.55, 14.14, 7.46),
            (160, 120, 64): (8.05, 12.19, 4.94), (160, 120, 128): (21.72, 19.31, 12.7),
            (320, 240, 32): (29.87, 38.04, 18.14)}


def duration(seconds: float) -> str:
    """``0.8 s``, ``42 s``, ``3 min 5 s``, ``2 h 10 min``: a time for people to read."""
    s = max(0.0, float(seconds))
    if s < 10:
        return f"{s:.1f} s"
    if s < 90:
        return f"{s:.0f} s"
    if s < 3600:
        m, r = divmod(round(s), 60)
        return f"{m} min" if s >= 600 or not r else f"{m} min {r} s"
    h, m = divmod(round(s / 60), 60)
    return f"{h} h {m} min" if m else f"{h} h"


@dataclass(frozen=True)
class Estimate:
    """A plan's estimated cost: CPU seconds in all, wall seconds with ``workers``, the paths traced."""

    cpu_s: float
    wall_s: float
    workers: int
    jobs: int
    paths: float
    kernel_s: float
    executor: str = "local"
    machine: str = MACHINE
    clean_max_factor: float = 0.0  # --clean-max-spp / --spp: the most a noisy cube's paths may grow

    def line(self) -> str:
        """One line for people: says it is an estimate and where it was measured."""
        slots = f"{self.workers} worker(s)" if self.executor == "local" else f"{self.workers} Ray task(s) at once"
        clean = (f"; generated rooms' cubes counted at {CLEAN_PATHS_FACTOR}x the paths, what the until-clean rule "
                 f"(--clean-max-spp, guided rounds included) cost on held-out rooms; one noisy cube can take up to "
                 f"{self.clean_max_factor:.3g}x, bench/SCENES.md" if self.clean_max_factor > 1 else "")
        return (f"estimate: about {duration(self.cpu_s)} CPU, {duration(self.wall_s)} wall with {slots} "
                f"for {self.jobs} job(s) ({self.paths / 1e6:.3g} M paths; up to {duration(self.kernel_s)} "
                f"of it building kernels{clean}) — scaled from per-path costs measured on {self.machine}; "
                "other machines and scenes differ")

    def to_json(self) -> dict:
        return {"estimate_cpu_s": round(self.cpu_s, 1), "estimate_wall_s": round(self.wall_s, 1),
                "estimate_machine": self.machine}


def boost_extra(settings, pixels: int) -> float:
    """The targeted extra paths as a share of a cube's paths (0 without the boost)."""
    factor = int(getattr(settings, "boost_factor", 1) or 1)
    if factor <= 1:
        return 0.0
    xs = [math.log(px) for px, _ in BOOST_SHARE]
    import numpy as np

    share = float(np.interp(math.log(max(1, pixels)), xs, [sh for _, sh in BOOST_SHARE]))  # flat outside
    return (factor - 1) * share


def _pixels(plan, job) -> int:
    v = plan.scenes[job.scene].view(job.view)
    return int(v.resolution[0]) * int(v.resolution[1])


def clean_factor(plan, job, settings) -> float:
    """The paths the until-clean rule adds to a cube, on average, as a factor of ``spp``
    (:data:`CLEAN_PATHS_FACTOR` where it applies, capped by ``clean_max_spp / spp``; 1 elsewhere)."""
    cap = settings.clean_cap(plan.scenes[job.scene])
    return min(CLEAN_PATHS_FACTOR, cap / float(settings.spp)) if cap else 1.0


def job_paths(plan, job, settings) -> float:
    """The paths a job traces (0 for a view job's AOVs, which are counted in its time)."""
    if job.group is None:
        return 0.0
    px = _pixels(plan, job)
    return px * float(settings.spp) * (1.0 + boost_extra(settings, px)) * clean_factor(plan, job, settings)


def job_cpu_s(plan, job, settings) -> float:
    """Estimated CPU seconds of one job with warm kernels (× :data:`GENERATED_COST_FACTOR` in a generated room)."""
    from illumix.renderer_jobs.render_settings import generated_room  # noqa: PLC0415 (progress imports this module)

    px = _pixels(plan, job)
    room = GENERATED_COST_FACTOR if generated_room(plan.scenes[job.scene]) else 1.0
    if job.group is None:
        return room * (VIEW_S + VIEW_PER_PIXEL_S * px * float(getattr(settings, "aov_spp", 16)) / 16)
    return room * (CUBE_S + CUBE_PER_PIXEL_S * px + PER_MPATH_S * job_paths(plan, job, settings) / 1e6)


def estimate(plan, settings, workers: int = 1, executor: str = "local") -> Estimate | None:
    """The estimated cost of ``plan``'s jobs with ``settings`` on ``workers`` local processes (Ray:
    ``workers`` is taken as the tasks running at once; one kernel build per task slot). None for a
    backend the table was not measured for (Cycles: 28–36× Mitsuba's CPU, bench/RENDER_PERF.md)."""
    if getattr(settings, "backend", "mitsuba") != "mitsuba":
        return None
    jobs = list(plan.jobs)
    workers = max(1, int(workers))
    work = sum(job_cpu_s(plan, j, settings) for j in jobs)
    paths = sum(job_paths(plan, j, settings) for j in jobs)
    kinds = {j.group for j in jobs if j.group is not None}
    per_process = KERNEL_BUILD_S * min(MAX_KINDS, max(1, len(kinds))) if jobs else 0.0
    used = min(workers, max(1, len(jobs)))
    kernel = per_process * used if jobs else 0.0
    cpu = work + kernel
    cores = os.cpu_count() or 1
    # a worker's jobs run with cores // workers threads (a Ray task with one): its share of the work,
    # at WALL_PER_CPU with several threads; never faster than every core busy
    threads = max(1, cores // used) if executor == "local" else 1
    ratio = WALL_PER_CPU if threads >= 2 else 1.0
    wall = max((per_process + work / used) * ratio, cpu / cores if executor == "local" else 0.0) if jobs else 0.0
    caps = [settings.clean_cap(plan.scenes[j.scene]) for j in jobs if j.group]
    return Estimate(cpu_s=cpu, wall_s=wall, workers=workers, jobs=len(jobs), paths=paths, kernel_s=kernel,
                    executor=executor, clean_max_factor=max(caps, default=0) / float(settings.spp))


def weights(plan, settings) -> dict[str, float]:
    """Each job's estimated CPU seconds by label: the progress lines' ETA weights."""
    return {j.label: job_cpu_s(plan, j, settings) for j in plan.jobs}
