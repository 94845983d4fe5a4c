"""Cycles worker, part 2: the material node trees (see :mod:`renderer_jobs.cycles.worker`).

Runs in Blender's Python beside the worker (imported from the worker's own folder): standard
library and bpy only. Every spectral input is set per pass by a *setter* the builder keeps:
``setter(bands, setup, mode)`` before each render.
"""

from __future__ import annotations


def _slots(values, bands) -> tuple[float, float, float]:
    """The R, G, B values of a pass: ``values[band]`` per slot, 0 for an unused slot (-1)."""
    return tuple(float(values[b]) if b >= 0 else 0.0 for b in bands)


class MaterialBuilder:
    """Mixin of the worker's scene builder: surface BSDFs, front-side emission, the
    white-Lambertian switch of the illumination cube and the AOV outputs, as node trees.
    Needs ``self.bpy`` and ``self.setters``."""

    def _material(self, name: str, m: dict | None, em: dict | None):
        """Node tree: the surface BSDF (black when none), emission on the front side only, the
        white-Lambertian switch for the illumination cube, and the AOV outputs."""
        bpy = self.bpy
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        N, L = nt.nodes.new, nt.links.new
        out = N("ShaderNodeOutputMaterial")
        geo = N("ShaderNodeNewGeometry")
        surf = self._bsdf(nt, m)
        if m is not None and not m.get("two_sided", True):
            black = N("ShaderNodeBsdfDiffuse")
            black.inputs["Color"].default_value = (0, 0, 0, 1)
            mix = N("ShaderNodeMixShader")
            L(geo.outputs["Backfacing"], mix.inputs["Fac"])
            L(surf, mix.inputs[1])
            L(black.outputs[0], mix.inputs[2])
            surf = mix.outputs[0]
        if em is not None:
            emit = N("ShaderNodeEmission")
            self._spectral_input(emit.inputs["Color"], em["radiance"], strength=emit.inputs["Strength"],
                                 active=lambda setup, em=em: (setup == "only") == em["portal"])
            front = N("ShaderNodeMixShader")  # emits from the front (normal) side only, like Mitsuba
            add = N("ShaderNodeAddShader")
            L(emit.outputs[0], add.inputs[0])
            L(surf, add.inputs[1])
            L(geo.outputs["Backfacing"], front.inputs["Fac"])
            L(add.outputs[0], front.inputs[1])
            L(surf, front.inputs[2])
            surf = front.outputs[0]
            mat.cycles.emission_sampling = "FRONT"
        # Illumination cube: camera rays see a white Lambertian surface (E/π), later bounces the
        # true materials; switched on per render by the value node.
        white = N("ShaderNodeBsdfDiffuse")
        white.inputs["Color"].default_value = (1, 1, 1, 1)
        lp = N("ShaderNodeLightPath")
        switch = N("ShaderNodeValue")
        mul = N("ShaderNodeMath")
        mul.operation = "MULTIPLY"
        L(lp.outputs["Is Camera Ray"], mul.inputs[0])
        L(switch.outputs[0], mul.inputs[1])
        gt = N("ShaderNodeMixShader")
        L(mul.outputs[0], gt.inputs["Fac"])
        L(surf, gt.inputs[1])
        L(white.outputs[0], gt.inputs[2])
        L(gt.outputs[0], out.inputs["Surface"])
        self.setters.append(lambda bands, setup, mode, s=switch: setattr(
            s.outputs[0], "default_value", 1.0 if mode == "illumination" else 0.0))
        # AOVs (the view's guides and masks)
        cam = N("ShaderNodeCameraData")
        for aov, value in (("albedo", None), ("normal", geo.outputs["Normal"]),
                           ("depth", cam.outputs["View Distance"]), ("emitter", None)):
            node = N("ShaderNodeOutputAOV")
            node.aov_name = aov
            if aov == "albedo":
                node.inputs["Color"].default_value = (*((m or {}).get("albedo_rgb") or (0, 0, 0)), 1)
            elif aov == "emitter":
                node.inputs["Value"].default_value = 1.0 if (em is not None and not em["portal"]) else 0.0
            elif aov == "normal":
                L(value, node.inputs["Color"])
            else:
                L(value, node.inputs["Value"])
        return mat

    def _spectral_input(self, socket, values, *, strength=None, active=None) -> None:
        """Set ``socket`` (a colour) to the pass's band values before each render; with
        ``strength`` the colour is normalised to ≤ 1 and its maximum goes to the strength input."""
        def setter(bands, setup, mode):
            rgb = _slots(values, bands) if (active is None or active(setup)) else (0.0, 0.0, 0.0)
            if strength is not None:
                peak = max(rgb)
                strength.default_value = peak
                rgb = tuple(c / peak for c in rgb) if peak > 0 else (0.0, 0.0, 0.0)
            socket.default_value = (*rgb, 1.0) if len(socket.default_value) == 4 else rgb  # colour / vector
        self.setters.append(setter)

    def _bsdf(self, nt, m: dict | None):
        N, L = nt.nodes.new, nt.links.new
        if m is None:  # an emitter without material: black
            d = N("ShaderNodeBsdfDiffuse")
            d.inputs["Color"].default_value = (0, 0, 0, 1)
            return d.outputs[0]
        kind = m["kind"]
        if kind == "diffuse":
            d = N("ShaderNodeBsdfDiffuse")
            d.inputs["Roughness"].default_value = 0.0
            self._spectral_input(d.inputs["Color"], m["reflectance"])
            return d.outputs[0]
        if kind == "plastic":
            pr = N("ShaderNodeBsdfPrincipled")
            pr.distribution = "GGX"
            pr.inputs["Roughness"].default_value = m["roughness"]
            pr.inputs["IOR"].default_value = m["ior"]
            pr.inputs["Metallic"].default_value = 0.0
            self._spectral_input(pr.inputs["Base Color"], m["diffuse"])
            return pr.outputs[0]
        if kind == "conductor":
            c = N("ShaderNodeBsdfMetallic")
            c.distribution = "GGX"
            c.fresnel_type = "PHYSICAL_CONDUCTOR"
            c.inputs["Roughness"].default_value = m["roughness"]
            self._spectral_input(c.inputs["IOR"], m["eta"])
            self._spectral_input(c.inputs["Extinction"], m["k"])
            return c.outputs[0]
        if kind == "glass":
            g = N("ShaderNodeBsdfGlass")
            g.distribution = "GGX"  # roughness 0: a smooth (sharp) interface
            g.inputs["Roughness"].default_value = 0.0
            g.inputs["IOR"].default_value = m["ior"]
            g.inputs["Color"].default_value = (1, 1, 1, 1)
            return g.outputs[0]
        raise RuntimeError(f"unknown material kind {kind!r}")
