"""The Mitsuba 3 backend (:mod:`renderer_jobs.backends`): one job at a time — a view's AOVs, or one
light group's transport cube (probed first when ``skip_dark``, with the denoiser's guides traced
first when the targeted extra paths are on) — on this machine's process pool or as Ray tasks. The
only backend module that reaches ``mitsuba`` (through the ``mitsuba_*`` modules)."""

from __future__ import annotations

import os
import time

import numpy as np

from illumix.renderer_jobs import jobs
from illumix.renderer_jobs.backends import JobBackend
from illumix.renderer_jobs.jobs import Job


class MitsubaBackend(JobBackend):
    name = "mitsuba"
    executors = ("local", "ray")

    def require(self) -> None:
        """Mitsuba 3 must be installed (the ``render`` extra): a service-only install has no renderer."""
        import importlib.util

        from illumix.renderer_jobs.backends import RenderError

        if importlib.util.find_spec("mitsuba") is None:
            raise RenderError("rendering needs Mitsuba 3, which this install lacks: pip install 'illumix[render]' "
                              "(or bash scripts/install.sh; on Debian also apt-get install libllvm19)")

    def render_cube(self, scene, view, group, settings):
        from illumix.renderer_jobs.mitsuba.render import render_cube

        return render_cube(scene, view, group, settings)

    def run_job(self, payload: tuple[dict, str | None], job: Job, store_path: str, settings_dict: dict,
                threads: int | None = None, overwrite: bool = False) -> dict:
        """Render one job with Mitsuba and write it into the store. Returns a small summary dict."""
        from illumix.renderer_jobs.mitsuba import render as mr
        from illumix.renderer_jobs.mitsuba.aovs import render_aovs
        from illumix.renderer_jobs.mitsuba.variant import select_variant

        if threads:
            os.environ.setdefault("DRJIT_NUM_THREADS", str(threads))
        scene = jobs._scene_from_payload(payload)
        settings = mr.RenderSettings(**settings_dict)
        select_variant()
        if threads:
            import drjit as dr

            try:
                dr.set_thread_count(int(threads))
            except Exception:  # noqa: BLE001 — cuda variants have no thread pool
                pass
        t0, c0 = time.perf_counter(), time.process_time()
        st = jobs._open_store(store_path, mode="a")
        if job.group is None:
            aovs = render_aovs(scene, job.view, settings)
            st.write_view(scene.name, job.view, jobs._view_meta(scene, job.view), aovs)
            return {"job": job.label, "seconds": time.perf_counter() - t0, "kind": "view",
                    "cpu_s": time.process_time() - c0}
        probe = None
        if settings.skip_dark:
            from illumix.renderer_jobs.mitsuba.light_probe import probe_group
            from illumix.renderer_jobs.mitsuba.scene_dict import group_emission

            probe = probe_group(scene, job.view, job.group, settings)
            if not probe.lit:
                # No pilot path carried light into the view: record the cube as empty, render nothing.
                emission, name = group_emission(scene, job.group)
                renderer = mr.renderer_info(scene, settings, mr.emitter_passes(scene, [job.group]))
                meta = jobs.cube_meta(scene, job, settings, np.asarray(emission, dtype=float).tolist(), name, renderer,
                                 {"skipped": "dark", "probe": probe.to_dict()})
                st.mark_empty(scene.name, job.view, job.group, meta, overwrite=overwrite)
                return {"job": job.label, "seconds": time.perf_counter() - t0, "kind": "cube", "empty": True,
                        "probe_s": probe.seconds, "cpu_s": time.process_time() - c0}
        prepared = mask = None
        if settings.boost_factor > 1:
            # The denoiser's guides (the group's direct light) first: the boost mask comes from them
            # alone, and the denoiser reuses them (traced once).
            from illumix.renderer_jobs.mitsuba.boost_paths import boost_mask

            prepared = jobs.denoise_guides(st, scene, job, settings)
            mask = boost_mask(prepared[0], settings.denoise, settings.boost_reach)
        result = mr.render_cube(scene, job.view, job.group, settings, boost_mask=mask)
        empty = jobs.store_result(st, scene, job, result, settings, overwrite,
                             {"probe": probe.to_dict()} if probe is not None else {}, prepared=prepared)
        return {"job": job.label, "seconds": time.perf_counter() - t0, "kind": "cube",
                "empty": empty, "trace_s": result.stats.get("trace_s"), "cpu_s": time.process_time() - c0}


BACKEND = MitsubaBackend()
