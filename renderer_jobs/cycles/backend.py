"""The Blender Cycles backend (:mod:`renderer_jobs.backends`), the thesis method: one Blender run per
view renders every pending light group (:mod:`renderer_jobs.cycles.jobs`), on this machine only
(Blender uses every core). Blender runs in its own Python (:mod:`scene.blender_env`); this
process never imports ``bpy``."""

from __future__ import annotations


class CyclesBackend:
    name = "cycles"
    executors = ("local",)
    executor_note = "Blender uses every core of this machine"

    def require(self) -> None:
        """Blender's ``bpy`` environment must be installed (``bash scripts/install.sh --blender``)."""
        from illumix.scene.blender_env import find_blender_python

        find_blender_python()

    def render_cube(self, scene, view, group, settings):
        from illumix.renderer_jobs.cycles import render as cycles_render

        return cycles_render.render_cube(scene, view, group, settings)

    def run(self, plan, store_path, settings_dict, *, executor, workers, address, on_done, ray_init, overwrite,
            on_pass, keep_going):
        from illumix.renderer_jobs.cycles.jobs import run_cycles

        return run_cycles(plan, store_path, settings_dict, on_done, overwrite, on_pass)


BACKEND = CyclesBackend()
