"""glTF 2.0 metallic-roughness materials as illumix materials (for :mod:`scene_import.gltf`).

What maps to what
-----------------
- **Kind**: metal (metalness ≥ 0.5) → ``roughconductor`` (``conductor: none``, tinted by the base
  colour's spectrum: glTF's metal Fresnel F0 is the base colour); dielectric → ``roughplastic`` (IOR
  1.5, glTF's dielectric specular) with the base colour divided by
  :func:`scene.plastic_scale.plastic_diffuse_scale` (Mitsuba's coating darkens the diffuse term,
  glTF's does not), or ``diffuse`` when roughness is 1. ``α = roughness²``.
  ``KHR_materials_transmission`` ≥ 0.5 → ``dielectric`` (``KHR_materials_ior``).
- **metallicRoughnessTexture** (B = metalness, G = roughness, × the factors): a primitive's triangles are
  split by the texels under them (:mod:`scene_import.gltf_textures`) into a metal and a dielectric
  part, each a material variant (``<name>-metal`` / ``<name>-dielectric`` beside ``<name>``) whose
  roughness is the mean over that class's texels and (metal) whose colour is the mean base colour over
  the metal texels. Without UVs the majority class takes the whole primitive. Warned as approximated.
- **baseColorTexture** → a PNG beside the scene with the factor baked in (sRGB), a
  :class:`~scene.textures.BitmapTexture`, on dielectric parts (Jakob–Hanika upsampling per texel).
- **emissiveTexture** (× ``emissiveFactor`` × ``KHR_materials_emissive_strength``): the triangles under
  emitting texels become area lights of their area-weighted mean colour; the rest do not emit.
  Without a texture the factor makes the whole shape emit, as before.
- **normalTexture** → the material's ``normal_map`` (``scale`` baked in; Mitsuba's ``normalmap`` BSDF),
  on primitives that have UVs (a variant without it on those that do not). Mirrored UVs get the
  unmirrored frame (illumix has no per-vertex tangents): a warning says so.
- Occlusion textures, alpha blending and other extensions are warnings naming the material.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable

import numpy as np

from illumix.scene_import import gltf_textures as tx
from illumix.scene_import.colour_match import reflectance, write_texture
from illumix.scene_import.names import key_name  # asset stems: the builder cuts a name at its first "."

SUPPORTED_EXT = {"KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_transmission",
                 "KHR_materials_ior"}


@dataclass
class GltfMaterial:
    """One glTF material: its illumix material variants, made on first use, and the maps that split
    a primitive's triangles among them. ``fixed``: a material without variants (dielectric glass)."""

    name: str
    what: str
    make: Callable[[bool, bool], str] | None = None  # (metal, with normal map) → material key
    metal: bool = False  # every triangle's class when there is no metalness map (or no UVs)
    metal_map: np.ndarray | None = None  # (H, W, 1) metalness, factor applied
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))  # linear RGB when no emissive map
    emissive_map: np.ndarray | None = None  # (H, W, 3) linear RGB emission, factors applied
    normal: bool = False
    fixed: str | None = None
    keys: dict = field(default_factory=dict)

    def key(self, metal: bool, normal: bool) -> str:
        if self.fixed is not None:
            return self.fixed
        k = (bool(metal), bool(normal and self.normal))
        if k not in self.keys:
            self.keys[k] = self.make(*k)
        return self.keys[k]

    def parts(self, pos, uv, tris: np.ndarray, warn, what: str) -> list[tuple]:
        """``[(suffix, triangle indices (k,), metal, emission linear RGB (3,) or None)]`` of a primitive
        with vertex positions ``pos`` ``(n, 3)``, UVs ``(n, 2)`` or None, ``tris`` ``(m, 3)`` (module docstring)."""
        m = len(tris)
        if self.fixed is not None:
            return [("", np.arange(m), False, None)]
        metal = np.full(m, self.metal)
        emit = np.full(m, bool(self.emission.max() > 0))
        em = np.broadcast_to(self.emission, (m, 3))
        maps = self.metal_map is not None or self.emissive_map is not None
        if maps and uv is None:
            warn(f"{what}: no TEXCOORD_0: the textures of {self.what} cannot be looked up; "
                 f"{'metal' if self.metal else 'dielectric'} and its mean emission used for the whole primitive")
            if self.emissive_map is not None:
                em = np.broadcast_to(self.emissive_map.reshape(-1, 3).mean(axis=0), (m, 3))
                emit[:] = em[0] @ tx.LUMINANCE > 0
        elif maps:
            if self.metal_map is not None:
                metal = tx.triangle_means(self.metal_map, uv, tris)[:, 0] >= 0.5
            if self.emissive_map is not None:
                em = tx.triangle_means(self.emissive_map, uv, tris)
                emit = tx.emitting(em, float((self.emissive_map @ tx.LUMINANCE).max()))
                warn(f"{what}: emissiveTexture of {self.what}: {int(emit.sum())} of {m} triangles emit (texels "
                     f"over {tx.EMIT_FRACTION:.0%} of the map's peak), each part its area-weighted mean colour "
                     "uniformly (approximated: an illumix area light has one radiance)")
        area = tx.triangle_areas(pos, tris)
        out = []
        for is_metal in (False, True):
            for is_emit in (False, True):
                sel = np.flatnonzero((metal == is_metal) & (emit == is_emit))
                if not len(sel):
                    continue
                rgb = None
                if is_emit:
                    w = area[sel] if area[sel].sum() > 0 else np.ones(len(sel))
                    rgb = (np.asarray(em)[sel] * w[:, None]).sum(axis=0) / w.sum()
                suffix = ("metal" if is_metal else "dielectric") + ("-emit" if is_emit else "")
                out.append((suffix, sel, is_metal, rgb))
        return out


def material(b, r, i: int, texture_image: Callable) -> GltfMaterial:
    """The :class:`GltfMaterial` of glTF material ``i`` (``texture_image(info, label, what)``: the PIL
    image of a texture info, or None with a warning)."""
    m = r.gltf.materials[i]
    name = getattr(m, "name", None) or f"material{i}"
    g = GltfMaterial(name, f"material {name!r}")
    warn, what, ext = b.warn, g.what, m.extensions or {}
    pbr = m.pbrMetallicRoughness
    factor, metallic, rough = _pbr_factors(m, ext, what, warn)
    trans = float((ext.get("KHR_materials_transmission") or {}).get("transmissionFactor", 0.0))
    strength = float((ext.get("KHR_materials_emissive_strength") or {}).get("emissiveStrength", 1.0))
    g.emission = np.asarray(m.emissiveFactor or [0, 0, 0], float) * strength
    if trans >= 0.5:
        ior = float((ext.get("KHR_materials_ior") or {}).get("ior", 1.5))
        warn(f"{what}: transmission {trans:g} → dielectric (IOR {ior:g}); base colour, roughness and textures "
             "not used")
        if g.emission.max() > 0:
            warn(f"{what}: a dielectric cannot emit in illumix; its emission is dropped")
        g.fixed = b.add_material(name, {"kind": "dielectric", "int_ior": min(max(ior, 1.0001), 4.0)})
        return g
    if trans > 0:
        warn(f"{what}: transmission {trans:g} < 0.5 is ignored (opaque)")
    base_img = texture_image(pbr.baseColorTexture, "baseColorTexture", what) if pbr and pbr.baseColorTexture else None
    mr_img = (texture_image(pbr.metallicRoughnessTexture, "metallicRoughnessTexture", what)
              if pbr and pbr.metallicRoughnessTexture else None)
    if m.emissiveTexture is not None and g.emission.max() > 0:
        em_img = texture_image(m.emissiveTexture, "emissiveTexture", what)
        if em_img is not None:
            g.emissive_map = tx.linear(em_img) * g.emission.astype(np.float32)
        else:  # the factor alone would light the whole surface (a glowing helmet): emit nothing instead
            warn(f"{what}: without its emissiveTexture the emission is unknown; the material does not emit")
            g.emission = np.zeros(3)
    normal_rel = _normal_map(b, m, name, what, texture_image)
    g.normal = normal_rel is not None
    stats = _metal_rough(g, factor, metallic, rough, base_img, mr_img, warn)
    g.make = _variant_maker(b, g, m, factor, base_img, normal_rel, stats)
    return g


def _metal_rough(g: GltfMaterial, factor, metallic: float, rough: float, base_img, mr_img, warn) -> dict:
    """Roughness per class and the metal colour; sets ``g.metal`` / ``g.metal_map`` (module docstring)."""
    metal_rgb = factor[:3]
    if mr_img is None:
        if 0 < metallic < 0.5 or 0.5 <= metallic < 1:
            warn(f"{g.what}: metallicFactor {metallic:g} rounded to {'metal' if metallic >= 0.5 else 'dielectric'}")
        g.metal = metallic >= 0.5
        if base_img is not None and g.metal:
            metal_rgb = metal_rgb * tx.linear(base_img).reshape(-1, 3).mean(axis=0)
            warn(f"{g.what}: a metal's baseColorTexture is averaged to one colour (conductor colours are spectra)")
        return {"rough": {False: rough, True: rough}, "metal_rgb": metal_rgb}
    mr = tx.raw(mr_img)
    g.metal_map = np.ascontiguousarray(mr[..., 2:3] * metallic)
    is_metal = g.metal_map[..., 0] >= 0.5
    g.metal = bool(is_metal.mean() >= 0.5)
    rmap = mr[..., 1:2] * rough
    r = {m: float(tx.class_mean(rmap, is_metal == m, [rough])[0]) for m in (False, True)}
    if base_img is not None and is_metal.any():
        base = tx.resized(tx.linear(base_img), is_metal.shape)
        metal_rgb = metal_rgb * tx.class_mean(base, is_metal, np.ones(3))
    warn(f"{g.what}: metallicRoughnessTexture: {is_metal.mean():.0%} of its texels are metal (B × metallicFactor "
         f"≥ 0.5); triangles are split into metal (roughconductor, roughness {r[True]:.3g}) and dielectric "
         f"(roughness {r[False]:.3g}) parts by the texels under them — each part takes its texels' mean roughness "
         "and a metal its mean base colour (approximated: illumix materials hold one roughness and one colour)")
    return {"rough": r, "metal_rgb": metal_rgb}


def _variant_maker(b, g: GltfMaterial, m, factor, base_img, normal_rel: str | None, stats: dict):
    """The function making material variant ``(metal, normal)`` of ``g`` (module docstring)."""
    two = bool(m.doubleSided)

    def make(metal: bool, normal: bool) -> str:
        rough = stats["rough"][metal]
        alpha = min(max(rough ** 2, 1e-3), 1.0)
        if metal:
            doc = {"kind": "roughconductor", "conductor": "none", "alpha": alpha,
                   "specular_reflectance": reflectance(stats["metal_rgb"], g.what, b.warn), "two_sided": two}
        else:
            plastic = rough < 0.999
            scale = 1.0
            if plastic:
                from illumix.scene.plastic_scale import plastic_diffuse_scale

                scale = plastic_diffuse_scale(alpha, 1.5)
            refl = _base_reflectance(b, base_img, factor[:3] / scale, scale, g.name, g.what, b.warn)
            doc = ({"kind": "roughplastic", "reflectance": refl, "alpha": alpha, "int_ior": 1.5, "two_sided": two}
                   if plastic else {"kind": "diffuse", "reflectance": refl, "two_sided": two})
        if normal:
            doc["normal_map"] = {"file": normal_rel}
        variant = ("metal" if metal else "dielectric") if metal != g.metal else ""
        return b.add_material("-".join(p for p in (g.name, variant, "" if normal or not g.normal
                                                   else "no-normal-map") if p), doc)

    return make


def _normal_map(b, m, name: str, what: str, texture_image) -> str | None:
    """The baked normal map's path (relative to the scene) or None (module docstring)."""
    if m.normalTexture is None:
        return None
    img = texture_image(m.normalTexture, "normalTexture", what)
    if img is None:
        return None
    scale = float(m.normalTexture.scale if m.normalTexture.scale is not None else 1.0)
    data, digest = tx.normal_png(img, scale)
    # the content hash in the file name puts the map's bytes into the scene document (and its hash)
    path, rel = b.file_path(key_name(f"{name}-normal-{digest}"), ".png")
    tx.write_bytes(path, data)
    b.warn(f"{what}: normal map imported as a tangent-space normalmap (frame from the UVs and shading normals; "
           "mirrored UV islands get the unmirrored frame)")
    return rel


def _pbr_factors(m, ext: dict, what: str, warn) -> tuple[np.ndarray, float, float]:
    """``(base colour factor (4,), metallic, roughness)`` of material ``m``; warns of what is ignored."""
    for e in sorted(set(ext) - SUPPORTED_EXT):
        warn(f"{what}: extension {e} is not supported; ignored")
    if m.occlusionTexture is not None:
        warn(f"{what}: occlusion texture is ignored (the renderer computes occlusion)")
    if (m.alphaMode or "OPAQUE") != "OPAQUE":
        warn(f"{what}: alphaMode {m.alphaMode} is ignored; the surface is opaque")
    pbr = m.pbrMetallicRoughness
    factor = np.asarray((pbr.baseColorFactor if pbr and pbr.baseColorFactor else [1, 1, 1, 1]), float)
    metallic = float(pbr.metallicFactor if pbr and pbr.metallicFactor is not None else 1.0)
    rough = float(pbr.roughnessFactor if pbr and pbr.roughnessFactor is not None else 1.0)
    return factor, metallic, rough


def _base_reflectance(b, texture, base: np.ndarray, scale: float, name: str, what: str, warn) -> dict:
    """The diffuse reflectance: ``texture`` × ``base`` (the base colour factor / ``scale``) as a PNG
    beside the scene, or without a texture ``base``'s spectrum; ``base`` is clipped to 1, with a warning."""
    if texture is not None:
        if texture.mode in ("RGBA", "LA", "PA") and np.asarray(texture.getchannel("A")).min() < 255:
            warn(f"{what}: the texture's alpha channel is ignored")
        path, rel = b.file_path(key_name(f"{name}-basecolor"), ".png")
        if base.max() > 1:  # baked per texel: only the texels the factor pushes over 1 are clipped
            texture, over = tx.with_factor(texture, base)
            if over > 0:
                warn(f"{what}: base colour texture × factor / {scale:.3g} (to render as bright as glTF's diffuse "
                     f"lobe) exceeds 1 in {over:.1%} of the texels; clipped there")
            base = np.ones(3)
        write_texture(texture, base, path)
        return {"file": rel}
    if base.max() > 1:
        warn(f"{what}: base colour / {scale:.3g} (to render as bright as glTF's diffuse lobe) exceeds 1; clipped")
    return reflectance(np.minimum(base, 1.0), what, warn)
