"""Cycles worker: renders one plain-data job with Blender's ``bpy`` and writes multilayer EXRs.

Runs in Blender's Python (``bpy`` 4.5 pins numpy < 2, which the rest of illumix cannot use, so it
lives in its own environment: :mod:`scene.blender_env`). It imports only the standard
library, numpy, bpy and its sibling :mod:`renderer_jobs.cycles.blender_nodes` (the material node trees) —
nothing of illumix — and knows nothing of spectra: the job
(:mod:`renderer_jobs.cycles.job` writes it) already holds band values, and each *pass* names the
three bands its R, G, B slots carry (the thesis method: 21 passes × 3 fixed wavelengths, the same
seed in every pass). Per pass it sets every colour to its bands' values and renders; one render
returns every light group's pass (``view_layer.lightgroups``, ``Combined_<group>`` in the EXR).

    python worker.py JOB_DIR        # reads JOB_DIR/job.json (+ meshes.npz), writes JOB_DIR/*.exr

Prints ``ILLUMIX-PROGRESS <done> <total> <label>`` lines (Blender's own log goes to stdout too).
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from blender_nodes import MaterialBuilder, _slots  # the worker's folder is on sys.path (run as a script)

PROGRESS = "ILLUMIX-PROGRESS"


def _log(done: int, total: int, label: str) -> None:
    print(f"{PROGRESS} {done} {total} {label}", flush=True)


class Builder(MaterialBuilder):
    """Builds the Blender scene of a job and keeps every per-pass setter."""

    def __init__(self, bpy, job: dict, job_dir: Path) -> None:
        self.bpy, self.job, self.dir = bpy, job, job_dir
        self.setters: list = []  # f(bands, setup, mode) called before each render
        self.portal_objects: list = []  # shapes shown only in the "only" setup
        arrays = job_dir / "meshes.npz"
        self.meshes = np.load(arrays) if arrays.is_file() else {}

    # -- scene -----------------------------------------------------------------------------------

    def build(self) -> None:
        bpy = self.bpy
        bpy.ops.wm.read_factory_settings(use_empty=True)
        sc = bpy.context.scene
        self.scene = sc
        self._settings(sc)
        vl = sc.view_layers[0]
        for g in self.job["groups"]:
            vl.lightgroups.add(name=g)
        for name in ("albedo", "normal"):
            a = vl.aovs.add()
            a.name, a.type = name, "COLOR"
        for name in ("depth", "emitter"):
            a = vl.aovs.add()
            a.name, a.type = name, "VALUE"
        self.materials = dict(self.job["materials"])
        for shape in self.job["shapes"]:
            self._shape(sc, shape)
        for light in self.job["lights"]:
            self._light(sc, light)
        self._world(sc)
        self._camera(sc)

    def _settings(self, sc) -> None:
        s = self.job["settings"]
        sc.render.engine = "CYCLES"
        cy = sc.cycles
        cy.device = "CPU"
        cy.samples = int(s["spp"])
        cy.seed = int(s["seed"])
        cy.use_animated_seed = False
        cy.use_adaptive_sampling = False
        cy.use_denoising = False
        cy.sample_clamp_direct = 0.0
        cy.sample_clamp_indirect = 0.0
        cy.use_light_tree = bool(s["light_tree"])
        cy.light_sampling_threshold = 0.0  # no light culling: unbiased
        cy.sampling_pattern = s["sampling_pattern"]
        cy.pixel_filter_type = "BOX"
        cy.filter_width = 1.0
        cy.blur_glossy = 0.0
        cy.caustics_reflective = True
        cy.caustics_refractive = True
        cy.use_guiding = False
        b = int(s["max_bounces"])
        cy.max_bounces = b
        cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = b
        cy.transparent_max_bounces = b
        cy.volume_bounces = 0
        cy.min_light_bounces = 0
        cy.film_exposure = 1.0
        sc.render.film_transparent = False
        sc.render.use_persistent_data = True  # the BVH is built once for all passes
        if s.get("threads"):
            sc.render.threads_mode = "FIXED"
            sc.render.threads = int(s["threads"])
        w, h = self.job["resolution"]
        sc.render.resolution_x, sc.render.resolution_y = int(w), int(h)
        sc.render.resolution_percentage = 100
        sc.render.pixel_aspect_x = sc.render.pixel_aspect_y = 1.0
        sc.view_settings.view_transform = "Standard"
        im = sc.render.image_settings
        im.file_format = "OPEN_EXR_MULTILAYER"
        im.color_depth = "32"
        im.exr_codec = "ZIP"

    def _camera(self, sc) -> None:
        from mathutils import Matrix, Vector

        c = self.job["camera"]
        o, t, up = (Vector(c[k]) for k in ("origin", "target", "up"))
        fwd = (t - o).normalized()
        right = fwd.cross(up).normalized()
        true_up = right.cross(fwd)
        m = Matrix.Identity(4)
        for i in range(3):  # Blender cameras look down -Z with +Y up
            m[i][0], m[i][1], m[i][2], m[i][3] = right[i], true_up[i], -fwd[i], o[i]
        cam = self.bpy.data.cameras.new("camera")
        cam.sensor_fit = "HORIZONTAL"
        cam.angle = math.radians(c["fov_deg"])
        cam.clip_start, cam.clip_end = 1e-4, 1e6
        ob = self.bpy.data.objects.new("camera", cam)
        ob.matrix_world = m
        sc.collection.objects.link(ob)
        sc.camera = ob

    # -- shapes and materials ---------------------------------------------------------------------

    def _mesh_object(self, sc, shape: dict):
        bpy = self.bpy
        if "file" in shape:
            before = set(bpy.data.objects)
            if shape["file_type"] == "obj":
                bpy.ops.wm.obj_import(filepath=shape["file"], forward_axis="Y", up_axis="Z")
            else:
                bpy.ops.wm.ply_import(filepath=shape["file"], forward_axis="Y", up_axis="Z")
            new = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
            if not new:
                raise RuntimeError(f"shape {shape['name']}: {shape['file']} holds no mesh")
            ob = new[0]
            if len(new) > 1:  # one object per shape: join the file's parts
                with bpy.context.temp_override(active_object=ob, selected_editable_objects=new):
                    bpy.ops.object.join()
            from mathutils import Matrix

            ob.matrix_world = Matrix(shape["matrix"])
            for p in ob.data.polygons:
                p.use_smooth = not shape.get("flat", False)
            ob.data.materials.clear()
            for c in list(ob.users_collection):
                c.objects.unlink(ob)
            sc.collection.objects.link(ob)
            return ob
        key = shape["mesh"]
        v, f = self.meshes[key + ".v"], self.meshes[key + ".f"]
        me = bpy.data.meshes.new(shape["name"])
        me.vertices.add(len(v))
        me.vertices.foreach_set("co", v.astype(np.float32).ravel())
        me.loops.add(f.size)
        me.loops.foreach_set("vertex_index", f.astype(np.int32).ravel())
        me.polygons.add(len(f))
        me.polygons.foreach_set("loop_start", (3 * np.arange(len(f))).astype(np.int32))
        me.polygons.foreach_set("use_smooth", np.full(len(f), bool(shape.get("smooth")), dtype=bool))
        me.update()
        me.validate()
        if shape.get("smooth") and key + ".n" in self.meshes:
            me.normals_split_custom_set_from_vertices(self.meshes[key + ".n"].astype(np.float32).tolist())
        ob = bpy.data.objects.new(shape["name"], me)
        sc.collection.objects.link(ob)
        return ob

    def _area_light(self, sc, shape: dict) -> None:
        """An emitter-only rectangle or disk as a Cycles area light: sampled by solid angle, far less
        noisy than the same emitting mesh (sampled by area). Radiance ``L`` ↔ power ``π A L``;
        emits along the light's −Z (the shape's normal), seen by every ray as in Mitsuba."""
        from mathutils import Matrix

        a, em = shape["area_light"], shape["emitter"]
        data = self.bpy.data.lights.new(shape["name"], "AREA")
        data.shape, data.size, data.size_y = a["shape"], a["size"], a["size_y"]
        data.spread = math.pi
        data.use_shadow = True
        ob = self.bpy.data.objects.new(shape["name"], data)
        ob.matrix_world = Matrix(a["matrix"])
        for flag in ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission"):
            setattr(ob, flag, True)
        ob.lightgroup = em["group"]
        sc.collection.objects.link(ob)
        if em["portal"]:
            self.portal_objects.append(ob)
        power = math.pi * a["area"]

        def setter(bands, setup, mode, data=data, values=em["radiance"], portal=em["portal"]):
            rgb = _slots(values, bands) if (setup == "only") == portal else (0.0, 0.0, 0.0)
            peak = max(rgb)
            data.energy = peak * power
            data.color = tuple(c / peak for c in rgb) if peak > 0 else (0.0, 0.0, 0.0)
        self.setters.append(setter)

    def _shape(self, sc, shape: dict) -> None:
        if "area_light" in shape:
            # The light, plus the shape itself as a black surface just behind its emitting side:
            # in the scene description an emitter without material is black geometry (it absorbs
            # and shadows), while a Cycles light lets rays through.
            self._area_light(sc, shape)
            ob = self._mesh_object(sc, shape)
            ob.data.materials.append(self._material(shape["name"] + ".black", None, None))
            if shape["emitter"]["portal"]:
                self.portal_objects.append(ob)
            return
        ob = self._mesh_object(sc, shape)
        em = shape.get("emitter")
        if em is not None:
            ob.lightgroup = em["group"]
            if em["portal"]:
                self.portal_objects.append(ob)
        mat = self._material(shape["name"], self.materials.get(shape.get("material")), em)
        ob.data.materials.append(mat)

    # -- lights ------------------------------------------------------------------------------------

    def _light(self, sc, light: dict) -> None:
        from mathutils import Vector

        bpy = self.bpy
        kind = light["type"]
        if kind == "sky":
            self.sky = light
            return
        data = bpy.data.lights.new(light["name"], {"point": "POINT", "spot": "SPOT", "sun": "SUN"}[kind])
        data.use_shadow = True
        if kind in ("point", "spot"):
            data.shadow_soft_size = 0.0
            data.use_soft_falloff = False
        if kind == "spot":
            data.spot_size = math.radians(2 * light["cutoff_deg"])
            data.spot_blend = light["blend"]
            data.show_cone = False
        if kind == "sun":
            data.angle = 0.0
        ob = bpy.data.objects.new(light["name"], data)
        if kind in ("point", "spot"):
            ob.location = Vector(light["position"])
        if kind in ("spot", "sun"):
            d = Vector(light["direction"]).normalized()
            ob.rotation_mode = "QUATERNION"
            ob.rotation_quaternion = d.to_track_quat("-Z", "Y")
        ob.lightgroup = light["group"]
        sc.collection.objects.link(ob)
        # Cycles: a point/spot light of power P has intensity P/(4π) W/sr; a sun's strength is irradiance
        scale = 4 * math.pi if kind in ("point", "spot") else 1.0
        values = [scale * v for v in light["radiance"]]

        def setter(bands, setup, mode, data=data, values=values):
            rgb = _slots(values, bands) if setup == "without" else (0.0, 0.0, 0.0)
            peak = max(rgb)
            data.energy = peak
            data.color = tuple(c / peak for c in rgb) if peak > 0 else (0.0, 0.0, 0.0)
        self.setters.append(setter)

    def _world(self, sc) -> None:
        bpy = self.bpy
        world = bpy.data.worlds.new("world")
        sc.world = world
        world.use_nodes = True
        nt = world.node_tree
        nt.nodes.clear()
        bg = nt.nodes.new("ShaderNodeBackground")
        out = nt.nodes.new("ShaderNodeOutputWorld")
        nt.links.new(bg.outputs[0], out.inputs["Surface"])
        sky = getattr(self, "sky", None)
        if sky is None:
            bg.inputs["Color"].default_value = (0, 0, 0, 1)
            bg.inputs["Strength"].default_value = 0.0
            return
        world.lightgroup = sky["group"]
        if "image" not in sky:
            self._spectral_input(bg.inputs["Color"], sky["radiance"], strength=bg.inputs["Strength"],
                                 active=lambda setup: setup == "without")
            return
        # An environment map, looked up as Mitsuba's envmap does: the direction d to the sky in the
        # map's frame (inverse to_world), u = atan2(d.x, -d.z) / 2π, v = acos(d.y) / π (top row at
        # v = 0; Blender's images start at the bottom). Its luminance scales the group spectrum.
        N, L = nt.nodes.new, nt.links.new
        coord = N("ShaderNodeTexCoord")
        rows = []
        for r in sky["to_local"]:
            dot = N("ShaderNodeVectorMath")
            dot.operation = "DOT_PRODUCT"
            dot.inputs[1].default_value = r
            L(coord.outputs["Generated"], dot.inputs[0])
            rows.append(dot.outputs["Value"])

        def node_math(op, a, b=None):
            n = N("ShaderNodeMath")
            n.operation = op
            for i, x in enumerate((a, b)):
                if x is None:
                    continue
                if isinstance(x, (int, float)):
                    n.inputs[i].default_value = x
                else:
                    L(x, n.inputs[i])
            return n.outputs[0]
        u = node_math("MULTIPLY", node_math("ARCTAN2", rows[0], node_math("MULTIPLY", rows[2], -1.0)),
                      1 / (2 * math.pi))
        v = node_math("SUBTRACT", 1.0, node_math("MULTIPLY", node_math("ARCCOSINE", rows[1]), 1 / math.pi))
        uv = N("ShaderNodeCombineXYZ")
        L(u, uv.inputs[0])
        L(v, uv.inputs[1])
        tex = N("ShaderNodeTexImage")
        tex.image = bpy.data.images.load(sky["image"])
        tex.interpolation, tex.extension = "Linear", "REPEAT"
        L(uv.outputs[0], tex.inputs["Vector"])
        lum = N("ShaderNodeRGBToBW")
        L(tex.outputs["Color"], lum.inputs[0])
        gain = node_math("MULTIPLY", lum.outputs[0], 0.0)
        L(gain, bg.inputs["Strength"])
        gain_input = gain.node.inputs[1]

        def setter(bands, setup, mode, values=sky["radiance"]):
            rgb = _slots(values, bands) if setup == "without" else (0.0, 0.0, 0.0)
            peak = max(rgb)
            gain_input.default_value = peak
            bg.inputs["Color"].default_value = (*(c / peak if peak > 0 else 0.0 for c in rgb), 1.0)
        self.setters.append(setter)

    # -- rendering ---------------------------------------------------------------------------------

    def set_setup(self, setup: str) -> None:
        """``"without"``: every emitter but portals (portals hidden); ``"only"``: portals alone."""
        for ob in self.portal_objects:
            ob.hide_render = setup != "only"

    def render(self, path: Path, bands, setup: str, mode: str) -> None:
        for f in self.setters:
            f(bands, setup, mode)
        self.scene.render.filepath = str(path)
        self.bpy.ops.render.render(write_still=True)


def run(job_dir: Path) -> None:
    import bpy

    job = json.loads((job_dir / "job.json").read_text())
    b = Builder(bpy, job, job_dir)
    b.build()
    renders: list[tuple[str, str, int, list[int]]] = []
    if job.get("aov_spp"):
        renders.append(("aov", "aov", -1, [-1, -1, -1]))
    for setup in job["setups"]:
        for mode in job["modes"]:
            for p, bands in enumerate(job["passes"]):
                renders.append((setup, mode, p, bands))
    total = len(renders)
    _log(0, total, "start")
    t0 = time.process_time()
    for i, (setup, mode, p, bands) in enumerate(renders):
        if setup == "aov":
            b.scene.cycles.samples = int(job["aov_spp"])
            b.scene.render.film_transparent = True
            b.set_setup("without")
            b.render(job_dir / "aov.exr", bands, "without", "transport")
            b.scene.cycles.samples = int(job["settings"]["spp"])
            b.scene.render.film_transparent = False
        else:
            b.set_setup(setup)
            b.render(job_dir / f"{setup}_{mode}_{p:02d}.exr", bands, setup, mode)
        _log(i + 1, total, f"{setup} {mode} pass {p + 1}/{len(job['passes'])}")
    (job_dir / "done.json").write_text(json.dumps({"renders": total, "worker_cpu_s": time.process_time() - t0,
                                                   "blender": bpy.app.version_string}))


if __name__ == "__main__":
    run(Path(sys.argv[1]))
