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

``--real [--world env|sky]`` builds instead the shapes real files have (issue 39), without lamps:

- ``Floor``: Principled (roughness 0.5) whose Base Color is an Image Texture ``tiles``, an 8 × 8 byte
  image packed into the file with quadrants (sRGB codes) red (204, 26, 26) at UV (0, 0), green
  (26, 204, 26) at u > ½, blue (26, 26, 204) at v > ½, grey 204 at both, and on its Normal input a
  tangent-space Normal Map node (strength 0.5) of a uniform 4 × 4 Non-Color image :data:`BUMP`;
  ``Block``: a 0.2 m cube
  without a UV map using the same material;
- ``Cube`` with a duplicate ``Cube.001`` (Blender's default name for a
  duplicate, sharing its mesh), both painted by ``GroupPaint``: a material whose Principled BSDF lives
  inside the node group ``PaintGroup`` and takes its base colour (0.1, 0.5, 0.2) and roughness 0.4 from
  the Group node's inputs;
- ``Glow.001``: a 0.4 m plane at z = 1.2 facing down, material ``GroupGlow``: an Emission node (white,
  strength from the inner group's input) two node groups deep, strength 5 set on the outer Group node;
- the world: ``env`` (default) an Environment Texture of a 64 × 32 image, packed into the file, whose
  quarters along u are red, green, blue and yellow above the horizon (× 0.25 below), strength 2;
  ``sky``: a Nishita Sky Texture (sun 30° up) at strength 0.05;
- ``Camera`` at (0, −4, 1) looking along +Y tilted 10° up, 32 × 24 px: floor, cubes and sky in view.

``--render OUT.exr FILE.blend`` renders FILE's camera with Cycles (16 spp, box filter) into a float EXR
and the same pixels as ``OUT.npy`` ``(H, W, 3)`` float32, top row first (scene-linear Rec. 709): the
reference the world-import test compares Mitsuba against.

``--gltf OUT.glb FILE.blend`` exports FILE with Blender's own glTF exporter (cameras included): a
Blender-exported glTF, dotted names and all.
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


def _group(bpy, name: str, inputs: list[tuple[str, str, object]]):
    """A shader node group with the given ``(name, socket type, default)`` inputs and a Shader output."""
    g = bpy.data.node_groups.new(name, "ShaderNodeTree")
    for n, kind, default in inputs:
        sock = g.interface.new_socket(n, in_out="INPUT", socket_type=kind)
        sock.default_value = default
    g.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    return g, g.nodes.new("NodeGroupInput"), g.nodes.new("NodeGroupOutput")


def _group_materials(bpy):
    """``GroupPaint`` (Principled inside a group) and ``GroupGlow`` (Emission two groups deep)."""
    paint, gin, gout = _group(bpy, "PaintGroup", [("Colour", "NodeSocketColor", (0.8, 0.8, 0.8, 1.0)),
                                                   ("Rough", "NodeSocketFloat", 0.5)])
    p = paint.nodes.new("ShaderNodeBsdfPrincipled")
    paint.links.new(gin.outputs["Colour"], p.inputs["Base Color"])
    paint.links.new(gin.outputs["Rough"], p.inputs["Roughness"])
    paint.links.new(p.outputs["BSDF"], gout.inputs["Shader"])
    inner, gin, gout = _group(bpy, "GlowInner", [("Power", "NodeSocketFloat", 1.0)])
    e = inner.nodes.new("ShaderNodeEmission")
    e.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    inner.links.new(gin.outputs["Power"], e.inputs["Strength"])
    inner.links.new(e.outputs["Emission"], gout.inputs["Shader"])
    outer, gin, gout = _group(bpy, "GlowOuter", [("Power", "NodeSocketFloat", 1.0)])
    node = outer.nodes.new("ShaderNodeGroup")
    node.node_tree = inner
    outer.links.new(gin.outputs["Power"], node.inputs["Power"])
    outer.links.new(node.outputs["Shader"], gout.inputs["Shader"])
    mats = []
    for mname, tree, values in (("GroupPaint", paint, {"Colour": (0.1, 0.5, 0.2, 1.0), "Rough": 0.4}),
                                ("GroupGlow", outer, {"Power": 5.0})):
        m = bpy.data.materials.new(mname)
        m.use_nodes = True
        nt = m.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        gnode = nt.nodes.new("ShaderNodeGroup")
        gnode.node_tree = tree
        for k, v in values.items():
            gnode.inputs[k].default_value = v
        nt.links.new(gnode.outputs["Shader"], nt.nodes["Material Output"].inputs["Surface"])
        mats.append(m)
    return mats


TILES = {(0, 0): (204, 26, 26), (0, 1): (26, 204, 26), (1, 0): (26, 26, 204), (1, 1): (204, 204, 204)}
BUMP = (128, 191, 238)  # a normal tilted ~30° towards +v, on a Normal Map node of strength 0.5


def _tiles_material(bpy):
    """``Tiles``: a Principled BSDF whose Base Color is the packed image of :data:`TILES`, keyed by
    (v > ½, u > ½) in Blender's UVs (v up)."""
    import numpy as np

    px = np.ones((8, 8, 4), np.float32)  # Blender's rows run bottom-up: row 0 is v = 0
    for (top, right), code in TILES.items():
        px[4 * top:4 * top + 4, 4 * right:4 * right + 4, :3] = np.array(code) / 255.0
    img = bpy.data.images.new("tiles", 8, 8, alpha=False)
    img.pixels.foreach_set(px.ravel())
    img.pack()
    m, p = _principled(bpy, "Tiles", (0.8, 0.8, 0.8), 0.5)
    tex = m.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = img, "Closest"
    m.node_tree.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    bumps = bpy.data.images.new("bumps", 4, 4, alpha=False)
    bumps.colorspace_settings.name = "Non-Color"
    bumps.pixels.foreach_set(np.tile(np.array([*BUMP, 255]) / 255.0, 16).astype(np.float32))
    bumps.pack()
    ntex = m.node_tree.nodes.new("ShaderNodeTexImage")
    ntex.image = bumps
    nmap = m.node_tree.nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = 0.5
    m.node_tree.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    m.node_tree.links.new(nmap.outputs["Normal"], p.inputs["Normal"])
    return m


def _world(bpy, kind: str):
    import numpy as np

    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    nt = world.node_tree
    bg = nt.nodes["Background"]
    if kind == "sky":
        tex = nt.nodes.new("ShaderNodeTexSky")
        tex.sky_type = "NISHITA"
        tex.sun_elevation = math.radians(30)
        bg.inputs["Strength"].default_value = 0.05
    else:
        w, h = 64, 32
        colours = np.array([[1, 0.05, 0.05], [0.05, 1, 0.05], [0.05, 0.05, 1], [1, 1, 0.05]], np.float32)
        px = np.repeat(colours, w // 4, axis=0)[None].repeat(h, axis=0)  # (h, w, 3), row 0 = the bottom
        px[: h // 2] *= 0.25  # below the horizon
        img = bpy.data.images.new("strips", w, h, float_buffer=True)
        img.pixels.foreach_set(np.concatenate([px, np.ones((h, w, 1), np.float32)], axis=2).ravel())
        img.pack()
        tex = nt.nodes.new("ShaderNodeTexEnvironment")
        tex.image = img
        bg.inputs["Strength"].default_value = 2.0
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    return world


def build_real(path: str, world: str = "env") -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    paint, glow = _group_materials(bpy)
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0, 0, 0))
    bpy.context.object.name = "Floor"
    tiles = _tiles_material(bpy)
    bpy.context.object.data.materials.append(tiles)
    bpy.ops.mesh.primitive_cube_add(size=0.2, location=(0.0, -1.0, 0.1))
    bpy.context.object.name = "Block"
    me = bpy.context.object.data
    while me.uv_layers:
        me.uv_layers.remove(me.uv_layers[0])
    me.materials.append(tiles)
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(-0.6, 0.2, 0.3))
    cube = bpy.context.object
    cube.name = "Cube"
    cube.data.materials.append(paint)
    dup = cube.copy()  # Blender names it "Cube.001", as Shift+D does
    dup.location = (0.6, 0.2, 0.3)
    sc.collection.objects.link(dup)
    bpy.ops.mesh.primitive_plane_add(size=0.4, location=(0, 0.5, 1.2), rotation=(math.pi, 0, 0))
    bpy.context.object.name = "Glow.001"
    bpy.context.object.data.materials.append(glow)
    cam = bpy.data.cameras.new("Camera")
    cam.lens, cam.sensor_width, cam.sensor_fit = 24.0, 36.0, "HORIZONTAL"
    cam_ob = bpy.data.objects.new("Camera", cam)
    cam_ob.location = (0.0, -4.0, 1.0)
    cam_ob.rotation_euler = (math.radians(100), 0.0, 0.0)  # along +Y, 10° up
    sc.collection.objects.link(cam_ob)
    sc.camera = cam_ob
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 32, 24, 100
    sc.world = _world(bpy, world)
    bpy.context.preferences.filepaths.save_version = 0
    out = Path(path).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=False)


def render(blend: str, exr: str) -> None:
    """Cycles' image of ``blend``'s camera (16 spp, box filter, no denoising) as a float EXR."""
    import bpy

    bpy.ops.wm.open_mainfile(filepath=str(Path(blend).resolve()))
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device, sc.cycles.samples, sc.cycles.use_denoising = "CPU", 16, False
    sc.cycles.pixel_filter_type, sc.cycles.seed = "BOX", 0
    sc.render.image_settings.file_format, sc.render.image_settings.color_depth = "OPEN_EXR", "32"
    sc.render.image_settings.color_mode = "RGB"
    sc.view_settings.view_transform = "Standard"
    sc.render.filepath = str(Path(exr).resolve())
    bpy.ops.render.render(write_still=True)
    import numpy as np

    img = bpy.data.images.load(str(Path(exr).resolve()))
    w, h = img.size
    px = np.array(img.pixels[:], np.float32).reshape(h, w, -1)[::-1, :, :3]  # top row first
    np.save(Path(exr).with_suffix(".npy"), np.ascontiguousarray(px))


def export_gltf(blend: str, glb: str) -> None:
    import bpy

    bpy.ops.wm.open_mainfile(filepath=str(Path(blend).resolve()))
    bpy.ops.export_scene.gltf(filepath=str(Path(glb).resolve()), export_format="GLB", export_cameras=True)


def main(argv: list[str]) -> int:
    args = [a for a in argv if not a.startswith("--")]
    if "--render" in argv and len(args) == 2:
        render(args[1], args[0])
        return 0
    if "--gltf" in argv and len(args) == 2:
        export_gltf(args[1], args[0])
        return 0
    if "--real" in argv and len(args) in (1, 2):
        build_real(args[0], args[1] if len(args) == 2 else "env")
        return 0
    if len(args) != 1:
        print("usage: make_test_blend.py OUT.blend [--no-camera] | OUT.blend --real [--world env|sky] | "
              "--render OUT.exr FILE.blend | --gltf OUT.glb FILE.blend", file=sys.stderr)
        return 2
    build(args[0], camera="--no-camera" not in argv)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
