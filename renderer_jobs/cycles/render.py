"""The Cycles backend: a view's transport cubes (every light group in one render) and its AOVs.

:mod:`renderer_jobs.cycles.job` writes the job, :mod:`renderer_jobs.cycles.worker` renders it in
Blender's Python (:mod:`scene.blender_env`), and this module reads the multilayer EXRs back
with OpenEXR: pass ``p``'s ``Combined_<group>`` R, G, B are the cube's bands ``p, p+21, p+42``.
The cube has the Mitsuba backend's layout, units (radiance per unit of the group's emission
spectrum, band averages) and metadata, plus ``renderer.method`` = the thesis method.
"""

from __future__ import annotations

import json
import resource
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from illumix.scene.blender_env import find_blender_python
from illumix.renderer_jobs.cycles.exr import read_exr
from illumix.renderer_jobs.cycles.job import METHOD, SAMPLING_PATTERN, write_job
from illumix.renderer_jobs.backends import RenderError
from illumix.renderer_jobs.cube import CubeResult
from illumix.renderer_jobs.mitsuba.scene_dict import group_emission  # an envmap's emission is Mitsuba's D65
from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scene.model import Scene

WORKER = Path(__file__).with_name("worker.py")
Progress = Callable[[int, int, str], None]


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_worker(job_dir: Path, progress: Progress | None = None) -> dict:
    """Run the Blender worker on ``job_dir``; returns its ``done.json`` plus wall and CPU seconds."""
    python, _ = find_blender_python()
    t0, c0 = time.perf_counter(), _children_cpu()
    proc = subprocess.Popen([python, str(WORKER), str(job_dir)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, bufsize=1)
    tail: list[str] = []
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith("ILLUMIX-PROGRESS "):
            _, done, total, label = (line.rstrip("\n").split(" ", 3) + [""])[:4]
            if progress is not None:
                progress(int(done), int(total), label)
        elif line.strip() and not line.startswith("Fra:"):
            tail = (tail + [line.rstrip()])[-12:]
    rc = proc.wait()
    if rc != 0 or not (job_dir / "done.json").is_file():
        errors = [t for t in tail if "Error" in t or "error" in t] or tail
        raise RenderError(f"Cycles worker failed (exit {rc}): {' | '.join(errors[-3:])[:600]}")
    out = json.loads((job_dir / "done.json").read_text())
    out.update(wall_s=time.perf_counter() - t0, cpu_s=_children_cpu() - c0)
    return out


def renderer_info(scene: Scene, settings: RenderSettings, version: str, job: dict) -> dict:
    n = len(job["passes"])
    return {"name": "cycles", "backend": "cycles", "version": version, "method": METHOD.format(n=n),
            "settings": {"engine": "CYCLES", "device": "CPU", "passes": n, "bands_per_pass": 3,
                         "pass_bands": job["passes"], "spp": settings.spp, "seed": settings.seed,
                         "same_seed_every_pass": True, "max_bounces": job["settings"]["max_bounces"],
                         "max_depth": scene.max_depth, "sampling_pattern": SAMPLING_PATTERN,
                         "light_tree": True, "adaptive_sampling": False, "denoiser": None,
                         "clamp_direct": 0.0, "clamp_indirect": 0.0, "light_threshold": 0.0,
                         "filter_glossy": 0.0, "rfilter": "box", "filter_width_px": 1.0,
                         "setups": job["setups"], "light_groups": "view_layer.lightgroups, one per illumix group"},
            "illumination_method": ("camera rays see a white Lambertian surface (a Light Path 'Is Camera Ray' "
                                    "switch in every material), later bounces the true materials: E/π")}


def render_cubes(scene: Scene, view: str, settings: RenderSettings = RenderSettings(),
                 groups: list[str] | None = None, progress: Progress | None = None,
                 warn: Callable[[str], None] = lambda msg: None) -> dict[str, CubeResult]:
    """Every group's cube of ``view`` from one Cycles run: ``{group: CubeResult}`` (only ``groups``
    when given; the render costs the same either way)."""
    version = find_blender_python()[1]
    wanted = scene.group_names if groups is None else groups
    for g in wanted:
        scene.group(g)
    with tempfile.TemporaryDirectory(prefix="illumix-cycles-") as tmp:
        d = Path(tmp)
        job = write_job(scene, view, d, spp=settings.spp, seed=settings.seed, resolution=settings.resolution,
                        illumination=settings.illumination, warn=warn)
        stats = run_worker(d, progress)
        w, h = job["resolution"]
        nb = scene.spectral_grid.n_bands
        cubes = {m: np.zeros((len(job["groups"]), h, w, nb), dtype=np.float32) for m in job["modes"]}
        for setup in job["setups"]:
            for mode in job["modes"]:
                for p, bands in enumerate(job["passes"]):
                    layers = read_exr(d / f"{setup}_{mode}_{p:02d}.exr")
                    for gi, gid in enumerate(job["groups"]):
                        rgb = layers[f"Combined_{gid}"]
                        for slot, b in enumerate(bands):
                            if b >= 0:
                                cubes[mode][gi, :, :, b] += rgb[..., slot]
    info = renderer_info(scene, settings, version, job)
    run_stats = {"total_s": round(stats["wall_s"], 3), "cpu_s": round(stats["cpu_s"], 3),
                 "renders": stats["renders"]}
    out: dict[str, CubeResult] = {}
    for gi, g in enumerate(job["group_names"]):
        if g not in wanted:
            continue
        emission, name = group_emission(scene, g)
        # Non-finite pixels (none seen so far) are zeroed and counted, per group, as Mitsuba's are.
        t, u = cubes["transport"][gi], (cubes["illumination"][gi] if "illumination" in cubes else None)
        bad = sum(int((~np.isfinite(c)).sum()) for c in (t, u) if c is not None)
        for c in (t, u):
            if c is not None:
                np.nan_to_num(c, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        out[g] = CubeResult(cube=t, emission=np.asarray(emission, dtype=float), emission_name=name,
                            renderer=info, stats={**run_stats, "non_finite_samples": bad}, illumination=u)
    return out


def render_cube(scene: Scene, view: str, group: str, settings: RenderSettings = RenderSettings(),
                progress: Progress | None = None) -> CubeResult:
    """One group's cube (the Mitsuba backend's signature; renders every group, keeps one)."""
    return render_cubes(scene, view, settings, [group], progress)[group]


def render_aovs(scene: Scene, view: str, settings: RenderSettings = RenderSettings(),
                progress: Progress | None = None) -> dict[str, np.ndarray]:
    """The view's geometry AOVs as :func:`renderer_jobs.mitsuba.aovs.render_aovs` defines them, from
    Cycles' AOV outputs over ``aov_spp`` box-filtered samples per pixel (means over the samples
    that hit geometry; ``mask`` where most of the pixel's samples hit)."""
    with tempfile.TemporaryDirectory(prefix="illumix-cycles-aov-") as tmp:
        d = Path(tmp)
        write_job(scene, view, d, spp=settings.spp, seed=settings.seed, resolution=settings.resolution,
                  aov_spp=max(1, settings.aov_spp))
        run_worker(d, progress)
        layers = read_exr(d / "aov.exr")
    cover = layers["Combined"][..., 3]
    hit = np.maximum(cover, 1e-12)[..., None]
    normal = layers["normal"][..., :3].astype(np.float64)
    norm = np.linalg.norm(normal, axis=-1, keepdims=True)
    return {"albedo": np.where(cover[..., None] > 0, layers["albedo"][..., :3] / hit, 0).astype(np.float32),
            "normal": np.where(norm > 0, normal / np.where(norm > 0, norm, 1), 0).astype(np.float32),
            "depth": np.where(cover > 0, layers["depth"][..., 0] / hit[..., 0], 0).astype(np.float32),
            "mask": cover > 0.5,
            "emitter": layers["emitter"][..., 0] > 0.5}
