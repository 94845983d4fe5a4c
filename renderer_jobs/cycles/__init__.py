"""The Blender Cycles backend (:mod:`renderer_jobs.backends`), the thesis method: ``bpy`` is imported
only by :mod:`.worker` (and its :mod:`.blender_nodes`), run by Blender's own Python as a script.

- :mod:`.backend` — ``BACKEND``: a view's groups per Blender run (:mod:`.jobs`), this machine only;
- :mod:`.job` — the scene as the plain-data job the worker reads; :mod:`.render` — runs the worker,
  reads its passes (:mod:`.exr`) back into cubes.
"""
