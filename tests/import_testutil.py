"""Small scene files the import tests write themselves (no third-party assets): a glTF with a
textured quad, a camera and punctual lights; an OBJ + MTL; a Mitsuba 3 XML scene."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

# 2×2 patches of 8-bit sRGB codes, [row][col] from the image's top-left: moderate, in-gamut colours
PATCHES = np.array([[[180, 60, 50], [70, 150, 80]], [[60, 90, 170], [200, 190, 120]]], dtype=np.uint8)


def texture_png(path: Path, size: int = 64) -> Path:
    from PIL import Image

    img = np.repeat(np.repeat(PATCHES, size // 2, axis=0), size // 2, axis=1)
    Image.fromarray(img, "RGB").save(path)
    return path


def write_gltf(path: Path, *, glb: bool = False, extra_material_ext: bool = True) -> Path:
    """Two quads (a textured one filling the camera's view, a red emissive one elsewhere), a camera at
    z = 4 framing [-1, 1]² exactly (yfov 2·atan(1/4), square), a white directional light down −z, a
    warm KHR point light and a spot light."""
    import pygltflib as g

    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: (0, 0) = image top-left
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    blob = quad.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    png = path.with_name(path.stem + "-tex.png")
    texture_png(png)
    views = [g.BufferView(buffer=0, byteOffset=0, byteLength=48), g.BufferView(buffer=0, byteOffset=48, byteLength=48),
             g.BufferView(buffer=0, byteOffset=96, byteLength=32), g.BufferView(buffer=0, byteOffset=128, byteLength=12)]
    acc = [g.Accessor(bufferView=0, componentType=5126, count=4, type="VEC3", min=[-1, -1, 0], max=[1, 1, 0]),
           g.Accessor(bufferView=1, componentType=5126, count=4, type="VEC3"),
           g.Accessor(bufferView=2, componentType=5126, count=4, type="VEC2"),
           g.Accessor(bufferView=3, componentType=5123, count=6, type="SCALAR")]
    prim = {"attributes": g.Attributes(POSITION=0, NORMAL=1, TEXCOORD_0=2), "indices": 3}
    mats = [g.Material(name="Painted", doubleSided=True,
                       pbrMetallicRoughness=g.PbrMetallicRoughness(baseColorTexture=g.TextureInfo(index=0),
                                                                   metallicFactor=0.0, roughnessFactor=1.0)),
            g.Material(name="Glow", emissiveFactor=[1.0, 0.2, 0.1], normalTexture=g.NormalMaterialTexture(index=0),
                       pbrMetallicRoughness=g.PbrMetallicRoughness(baseColorFactor=[0.5, 0.5, 0.5, 1],
                                                                   metallicFactor=0.0, roughnessFactor=0.5),
                       extensions={"KHR_materials_clearcoat": {"clearcoatFactor": 1.0}} if extra_material_ext else {})]
    lights = [{"name": "Sun", "type": "directional", "color": [1.0, 1.0, 1.0], "intensity": 3.0},
              {"name": "Lamp warm", "type": "point", "color": [1.0, 0.6, 0.3], "intensity": 20.0, "range": 10.0},
              {"name": "Spot", "type": "spot", "color": [1.0, 1.0, 1.0], "intensity": 5.0,
               "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}]
    s = math.sqrt(0.5)
    nodes = [g.Node(name="Canvas", mesh=0),
             g.Node(name="GlowPanel", mesh=1, translation=[0, 3, -2], rotation=[s, 0, 0, s], scale=[0.5, 0.5, 0.5]),
             g.Node(name="Cam", camera=0, translation=[0, 0, 4]),
             g.Node(name="SunNode", extensions={"KHR_lights_punctual": {"light": 0}}),
             g.Node(name="LampNode", translation=[1, 2, 3], extensions={"KHR_lights_punctual": {"light": 1}}),
             g.Node(name="Rig", translation=[0, 1, 0], children=[6]),
             g.Node(name="SpotNode", translation=[0, 2, 0], rotation=[-s, 0, 0, s],
                    extensions={"KHR_lights_punctual": {"light": 2}})]
    doc = g.GLTF2(
        asset=g.Asset(version="2.0"), scene=0, scenes=[g.Scene(nodes=[0, 1, 2, 3, 4, 5])], nodes=nodes,
        meshes=[g.Mesh(name="CanvasMesh", primitives=[g.Primitive(material=0, **prim)]),
                g.Mesh(name="GlowMesh", primitives=[g.Primitive(material=1, **prim)])],
        materials=mats, textures=[g.Texture(source=0, sampler=0)], samplers=[g.Sampler()],
        images=[g.Image(uri=png.name)],
        cameras=[g.Camera(name="Front", type="perspective",
                          perspective=g.Perspective(yfov=2 * math.atan(0.25), aspectRatio=1.0, znear=0.01))],
        accessors=acc, bufferViews=views, buffers=[g.Buffer(byteLength=len(blob))],
        extensionsUsed=["KHR_lights_punctual"] + (["KHR_materials_clearcoat"] if extra_material_ext else []),
        extensions={"KHR_lights_punctual": {"lights": lights}})
    doc.set_binary_blob(blob)
    if glb:
        doc.save_binary(str(path))
    else:
        doc.convert_buffers(g.BufferFormat.DATAURI)
        doc.save_json(str(path))
    return path


def write_obj(path: Path) -> Path:
    """An OBJ + MTL: a textured floor (map_Kd), a glossy red box side (Kd, Ks, Ns), and an emissive
    ceiling panel (Ke) — two materials used by faces of the same object, one by another object."""
    png = path.with_name(path.stem + "-floor.png")
    texture_png(png, 16)
    path.with_suffix(".mtl").write_text(
        "newmtl floor\nKd 1 1 1\nmap_Kd " + png.name + "\nbump floor-bump.png\n\n"
        "newmtl red\nKd 0.6 0.1 0.1\nKs 0.04 0.04 0.04\nNs 100\n\n"
        "newmtl lamp\nKd 0.8 0.8 0.8\nKe 4 4 4\n")
    path.write_text(
        f"mtllib {path.with_suffix('.mtl').name}\n"
        "o room\n"
        "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\n"
        "v -1 0 -1\nv -1 1 -1\nv -1 1 1\nv -1 0 1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "vn 0 1 0\nvn 1 0 0\n"
        "usemtl floor\nf 1/1/1 4/4/1 3/3/1 2/2/1\n"
        "usemtl red\nf 5//2 6//2 7//2 8//2\n"
        "o panel\n"
        "v -0.5 2.5 -0.5\nv 0.5 2.5 -0.5\nv 0.5 2.5 0.5\nv -0.5 2.5 0.5\n"
        "usemtl lamp\nf 9 10 11 12\n")
    return path


def write_xml(path: Path) -> Path:
    """A Mitsuba 3 XML scene: $variables, a lookat sensor, a twosided diffuse rgb floor (rectangle scaled
    and rotated), a sphere with a spectrum reflectance, a cube with a bitmap texture, an area light,
    a warm point light, an unsupported BSDF and an unsupported emitter."""
    texture_png(path.with_name("checker.png"), 8)
    path.write_text("""<scene version="3.0.0">
  <default name="spp" value="16"/>
  <default name="res" value="64"/>
  <integrator type="path"><integer name="max_depth" value="6"/></integrator>
  <sensor type="perspective" id="cam">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 2, 5" target="0, 0.5, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
    <film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="48"/></film>
  </sensor>
  <bsdf type="twosided" id="floor-mat"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf></bsdf>
  <texture type="bitmap" id="tex"><string name="filename" value="checker.png"/></texture>
  <bsdf type="diffuse" id="textured"><ref name="reflectance" id="tex"/></bsdf>
  <shape type="rectangle" id="floor">
    <transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/><translate y="-0.01"/></transform>
    <ref id="floor-mat"/>
  </shape>
  <shape type="sphere" id="ball">
    <point name="center" x="0.5" y="0.5" z="0"/><float name="radius" value="0.5"/>
    <bsdf type="roughplastic"><spectrum name="diffuse_reflectance" value="400:0.1, 500:0.2, 600:0.6, 700:0.7"/>
      <float name="alpha" value="0.2"/><string name="distribution" value="ggx"/></bsdf>
  </shape>
  <shape type="cube" id="box">
    <transform name="to_world"><scale value="0.3"/><translate x="-1" y="0.3"/></transform>
    <ref id="textured"/>
  </shape>
  <shape type="sphere" id="velvet-ball">
    <point name="center" x="1.5" y="0.3" z="1"/><float name="radius" value="0.3"/>
    <bsdf type="hair"/>
  </shape>
  <shape type="cylinder" id="rail">
    <point name="p0" x="-1" y="0" z="-1"/><point name="p1" x="-1" y="2" z="-1"/><float name="radius" value="0.02"/>
    <bsdf type="conductor"><string name="material" value="Au"/></bsdf>
  </shape>
  <shape type="rectangle" id="ceiling_panel">
    <transform name="to_world"><rotate x="1" angle="90"/><translate y="3"/></transform>
    <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter>
  </shape>
  <emitter type="point" id="Lamp1">
    <point name="position" x="1" y="2" z="1"/><rgb name="intensity" value="10, 6, 3"/>
  </emitter>
  <emitter type="sunsky" id="sky"/>
</scene>
""")
    return path
