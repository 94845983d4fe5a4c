"""Issue 39: imported lights give mixed illuminants by default (daylight / warm / cool groups), a rule
file overrides that; emitters' spectra are kept (λ:value tables exactly, blackbodies by temperature),
approximations are warnings naming the light; an environment-map group renders."""

from __future__ import annotations

import itertools

import colour
import numpy as np
import pytest

from illumix.scene.load import scene_from_dict
from illumix.scene_import import import_scene
from illumix.scene_import.rules import load_rules

TABLE = "400:1, 450:1.4, 500:1.2, 550:1, 600:0.9, 650:0.8, 700:0.7"  # a bluish (~7750 K) panel
CORNELL = "10, 6, 3"  # a warm RGB light (~3670 K)


def write_scene(folder):
    from PIL import Image

    sky = np.zeros((8, 16, 3), np.uint8)
    sky[:4] = (120, 160, 230)  # blue upper hemisphere, grey ground
    sky[4:] = (90, 90, 90)
    Image.fromarray(sky, "RGB").save(folder / "sky.png")
    (folder / "s.xml").write_text(f"""<scene version="3.0.0">
  <sensor type="perspective" id="cam"><float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 1, 4" target="0, 0.5, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="18"/></film></sensor>
  <shape type="rectangle" id="floor"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"/></shape>
  <shape type="sphere" id="ball"><point name="center" x="0" y="0.5" z="0"/><float name="radius" value="0.5"/>
    <bsdf type="diffuse"/></shape>
  <emitter type="point" id="bulb"><point name="position" x="1" y="2" z="1"/>
    <spectrum name="intensity" type="blackbody"><float name="temperature" value="2700"/></spectrum></emitter>
  <shape type="rectangle" id="panel"><transform name="to_world"><rotate x="1" angle="90"/><translate y="3"/></transform>
    <emitter type="area"><spectrum name="radiance" value="{TABLE}"/></emitter></shape>
  <shape type="disk" id="cornell"><transform name="to_world"><rotate x="1" angle="90"/><translate x="-2" y="3"/></transform>
    <emitter type="area"><rgb name="radiance" value="{CORNELL}"/></emitter></shape>
  <emitter type="envmap" id="sky"><string name="filename" value="sky.png"/><float name="scale" value="0.5"/></emitter>
  <emitter type="directional" id="sun"><vector name="direction" x="0" y="-1" z="-1"/>
    <rgb name="irradiance" value="3, 3, 3"/></emitter>
</scene>""")
    return folder / "s.xml"


def _band_means(wl, v, edges):
    """Band averages of the linear interpolation of ``(wl, v)``, zero outside it (as Mitsuba), by
    fine midpoint sampling (0.01 nm)."""
    out = []
    for a, b in itertools.pairwise(edges):
        x = np.arange(a, b, 0.01) + 0.005
        out.append(np.interp(x, wl, v, left=0.0, right=0.0).mean())
    return np.asarray(out)


def test_default_groups_mix_illuminants_and_keep_spectra(tmp_path):
    doc, warns = import_scene(write_scene(tmp_path), tmp_path / "out")
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    lights = {li.name: li for li in scene.lights}
    g_of = {**{n: s.emitter.group for n, s in shapes.items() if s.emitter}, **{n: li.group for n, li in lights.items()}}
    assert g_of["sky"] == g_of["sun"] == "daylight" and scene.group("daylight").kind == "daylight"
    assert scene.group("daylight").emission == "flat"  # what the renderer needs for an envmap group
    assert g_of["bulb"].startswith("warm") and g_of["cornell"].startswith("warm") and g_of["panel"] == "cool"
    assert len(scene.group_names) >= 3 and scene.group("cool").kind == "artificial"
    # the blackbody keeps its temperature; its strength is Planck's luminance (W/(m²·sr·nm)) relative
    # to the flat unit spectrum, computed here from the formula over the grid's range
    assert scene.group(g_of["bulb"]).emission == "blackbody:2700"
    nm = np.arange(395.0, 705.0, 0.5) + 0.25
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    planck = 2 * h * c**2 / (nm * 1e-9) ** 5 / np.expm1(h * c / (nm * 1e-9 * k * 2700)) * 1e-9
    ybar = np.interp(nm, colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].wavelengths,
                     colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].values[:, 1])
    assert lights["bulb"].strength == pytest.approx((planck @ ybar) / ybar.sum(), rel=5e-3)
    # the λ:value table comes back exactly: strength × the group's (normalised) spectrum = the table
    wl, v = np.array([[float(x) for x in p.split(":")] for p in TABLE.split(", ")]).T
    got = shapes["panel"].emitter.strength * scene.emission("cool")
    want = _band_means(wl, v, scene.spectral_grid.edges)
    assert np.allclose(got[1:-1], want[1:-1], rtol=1e-3), (got, want)  # end bands: the zero step inside them
    # an RGB light is approximated, and said so, naming it and what it became
    warm_rgb = scene.group(g_of["cornell"]).emission
    assert warm_rgb.startswith("blackbody:3")
    assert any("'cornell'" in w and f"approximated by {warm_rgb}" in w and "rgb" in w for w in warns), warns
    assert any("'sun'" in w and "D65" in w for w in warns) is False  # white sun in the map's group: D65 exactly


def test_envmap_group_renders(tmp_path):
    pytest.importorskip("mitsuba")
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.renderer_jobs.render_settings import RenderSettings

    doc, _ = import_scene(write_scene(tmp_path), tmp_path / "out")
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    cube = render_cube(scene, "cam", "daylight", RenderSettings(spp=4)).cube
    assert cube.shape[:2] == (18, 24) and np.all(np.isfinite(cube)) and float(cube.mean()) > 0


def test_rule_file_overrides_the_default(tmp_path):
    rules = tmp_path / "rules.yaml"
    rules.write_text("groups:\n  - {name: lamps, match: ['bulb', 'cornell'], illuminant: A}\n"
                     "default_group: rest\n")
    doc, warns = import_scene(write_scene(tmp_path), tmp_path / "out", load_rules(rules))
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    assert scene.group_names == ["lamps", "rest"]
    assert scene.group("lamps").emission == "A" and scene.group("rest").emission == "flat"  # rest holds the map
    assert any("'bulb'" in w and "approximated by A" in w for w in warns)
    rules.write_text("grouping: each\n")
    doc, _ = import_scene(write_scene(tmp_path), tmp_path / "o2", load_rules(rules))
    assert [g["name"] for g in doc["light_groups"]] == ["bulb", "panel", "cornell", "sky", "sun"]


def test_rule_names_are_kept_when_a_default_group_has_the_same_name(tmp_path):
    rules = tmp_path / "rules.yaml"
    rules.write_text("groups:\n  - {name: warm, match: ['panel'], illuminant: FL2}\n")  # a cool panel, named warm
    doc, _ = import_scene(write_scene(tmp_path), tmp_path / "out", load_rules(rules))
    groups = {g["name"]: g for g in doc["light_groups"]}
    assert groups["warm"]["emission"] == "FL2"
    assert next(s for s in doc["shapes"] if s["name"] == "panel")["emitter"]["group"] == "warm"
    assert {next(li for li in doc["lights"] if li["name"] == "bulb")["group"]} <= {"warm-2", "warm-3"}


def test_uniform_and_float_emission_are_what_mitsuba_emits(tmp_path):
    """Mitsuba 3 (spectral) emits ``<spectrum value="v"/>`` as a uniform spectrum and ``<float>`` as D65 × v."""
    (tmp_path / "u.xml").write_text("""<scene version="3.0.0">
      <shape type="rectangle" id="flat_panel"><emitter type="area"><spectrum name="radiance" value="2"/></emitter></shape>
      <shape type="disk" id="d65_panel"><emitter type="area"><float name="radiance" value="3"/></emitter></shape>
      </scene>""")
    doc, warns = import_scene(tmp_path / "u.xml", tmp_path / "out")
    scene = scene_from_dict(doc, source="imported", base=tmp_path / "out")
    shapes = {s.name: s for s in scene.shapes}
    assert scene.group(shapes["flat_panel"].emitter.group).emission == "E" and shapes["flat_panel"].emitter.strength == 2
    assert scene.group(shapes["d65_panel"].emitter.group).emission == "D65" and shapes["d65_panel"].emitter.strength == 3
    assert np.allclose(scene.emission(shapes["flat_panel"].emitter.group), 1.0)
    assert not any("panel" in w for w in warns), warns
    # the default view frames both panels (unit rectangle and disk at the origin), not a point
    assert np.linalg.norm(scene.views[0].origin) > 1
