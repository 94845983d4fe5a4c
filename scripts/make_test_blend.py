"""Build the small deterministic ``.blend`` scene the blend-import tests read.

Run with Blender's Python (``bpy`` 4.5; see :mod:`scene.blender_env`)::

    ~/.cache/illumix/blender-venv/bin/python scripts/make_test_blend.py OUT.blend [--no-camera]

Blender world coordinates (metres, +Z up). Contents:

- ``Floor``: a 4 m × 4 m plane at z = 0, grey Principled BSDF (base colour 0.5, roughness 0.5);
- ``Cube``: 0.6 m cube, red Principled BSDF whose material carries the custom property
  ``illumix_reflectance = "ColorChecker N Ohta/red"`` (a measured reflectance replaces the colour);
- ``Sphere``: smooth UV sphere with a Subdivision Surface modifier, blue Diffuse BSDF
  (0.05, 0.1, 0.6) linear sRGB;
- ``Vase``: a cone whose Principled "Base Color" is linked to a Noise Texture (must warn);
- ``Panel``: 1 m × 0.5 m rectangular area light, 100 W, at z = 2.5 facing down, in collection
  ``ceiling``;
- ``Bulb``: 50 W point light with the custom property ``illumix_group = "lamp"``;
- ``Camera``: 35 mm lens on a 36 mm sensor, 128 × 96 px at 50 % (= 64 × 48), looking at the cube;
- a dim grey world background (0.02, strength 1).

``--no-camera`` leaves the camera out (for the error test).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path


def _principled(bpy, name: str, rgb, roughness: float):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*rgb, 1.0)
    p.inputs["Roughness"].default_value = roughness
    return m, p


def _diffuse(bpy, name: str, rgb):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*rgb, 1.0)
    nt.links.new(d.outputs["BSDF"], nt.nodes["Material Output"].inputs["Surface"])
    return m


def build(path: str, camera: bool = True) -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene

    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0, 0, 0))
    floor = bpy.context.object
    floor.name = "Floor"
    floor.data.materials.append(_principled(bpy, "Grey", (0.5, 0.5, 0.5), 0.5)[0])

    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(-0.6, 0.2, 0.3), rotation=(0, 0, math.radians(20)))
    cube = bpy.context.object
    cube.name = "Cube"
    red, _ = _principled(bpy, "Red", (0.6, 0.05, 0.04), 0.6)
    red["illumix_reflectance"] = "ColorChecker N Ohta/red"
    cube.data.materials.append(red)

    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=0.3, location=(0.5, -0.2, 0.3))
    sphere = bpy.context.object
    sphere.name = "Sphere"
    bpy.ops.object.shade_smooth()
    sphere.modifiers.new("Subdivision", "SUBSURF").levels = 1
    sphere.data.materials.append(_diffuse(bpy, "Blue", (0.05, 0.1, 0.6)))

    bpy.ops.mesh.primitive_cone_add(vertices=12, radius1=0.15, depth=0.5, location=(0.1, 0.7, 0.25))
    vase = bpy.context.object
    vase.name = "Vase"
    tex, p = _principled(bpy, "Speckled", (0.8, 0.8, 0.8), 0.4)
    noise = tex.node_tree.nodes.new("ShaderNodeTexNoise")
    tex.node_tree.links.new(noise.outputs["Color"], p.inputs["Base Color"])
    vase.data.materials.append(tex)

    ceiling = bpy.data.collections.new("ceiling")
    sc.collection.children.link(ceiling)
    area = bpy.data.lights.new("Panel", "AREA")
    area.shape, area.size, area.size_y, area.energy = "RECTANGLE", 1.0, 0.5, 100.0
    panel = bpy.data.objects.new("Panel", area)
    panel.location = (0.0, 0.0, 2.5)  # default orientation: emits along -Z, i.e. down
    ceiling.objects.link(panel)

    point = bpy.data.lights.new("Bulb", "POINT")
    point.energy = 50.0
    bulb = bpy.data.objects.new("Bulb", point)
    bulb.location = (1.0, -1.0, 1.5)
    bulb["illumix_group"] = "lamp"
    sc.collection.objects.link(bulb)

    if camera:
        cam = bpy.data.cameras.new("Camera")
        cam.lens, cam.sensor_width, cam.sensor_fit = 35.0, 36.0, "AUTO"
        cam_ob = bpy.data.objects.new("Camera", cam)
        cam_ob.location = (0.0, -4.0, 1.5)
        cam_ob.rotation_euler = (math.radians(75), 0.0, 0.0)  # looks along +Y, tilted down 15°
        sc.collection.objects.link(cam_ob)
        sc.camera = cam_ob
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 128, 96, 50

    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.02, 0.02, 0.02, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    sc.world = world

    bpy.context.preferences.filepaths.save_version = 0  # no OUT.blend1 backup when overwriting
    out = Path(path).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=False)


def main(argv: list[str]) -> int:
    args = [a for a in argv if not a.startswith("--")]
    if len(args) != 1:
        print("usage: make_test_blend.py OUT.blend [--no-camera]", file=sys.stderr)
        return 2
    build(args[0], camera="--no-camera" not in argv)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
