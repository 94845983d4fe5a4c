"""Procedural interiors: rooms, windows, light fixtures, furniture, appliances and clutter as detailed
triangle meshes, dressing (curtains, doors, wall items, things on every top), materials drawn from
measured reflectance sets with textures at physical scale, and camera views chosen for mixed light —
each scene a plain :class:`scene.model.Scene` document, reproducible from (:data:`GENERATOR_VERSION`,
seed).

Imports flow one way: ``retarget, renderer_jobs ← scenegen`` (the CLI wires it to the render jobs).
"""

GENERATOR_VERSION = "3"
