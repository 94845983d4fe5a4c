"""Importing Blender ``.blend`` files (:mod:`scene_import.blend`): the scene that
``scripts/make_test_blend.py`` builds, read back through Blender's Python and checked piece by piece."""

from __future__ import annotations

import math
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest

from illumix.scene_import import blend as blend_import
from illumix.scene.schema import LibrarySpectrum, SceneError, TableSpectrum

try:
    from illumix.scene.blender_env import find_blender_python
except ImportError:  # a checkout without the Cycles backend: the importer's own copy of the search
    from illumix.scene_import.blend import find_blender_python

BLENDER = find_blender_python(required=False)
pytestmark = pytest.mark.skipif(BLENDER is None, reason="Blender's Python (bpy) is not installed; "
                                "`bash scripts/install.sh --blender` installs it")
SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "make_test_blend.py"


def _make(path: Path, *extra: str) -> Path:
    r = subprocess.run([BLENDER[0], str(SCRIPT), str(path), *extra], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and path.is_file(), r.stderr[-2000:]
    return path


@pytest.fixture(scope="session")
def blend(tmp_path_factory) -> Path:
    return _make(tmp_path_factory.mktemp("blend") / "test scene.blend")


@pytest.fixture(scope="session")
def imported(blend, tmp_path_factory):
    """``(scene, warning messages, cache dir)`` of the test file."""
    cache = tmp_path_factory.mktemp("blend-cache") / "out"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scenes = blend_import.load_blend(blend, cache_dir=cache)
    assert len(scenes) == 1
    return scenes[0], [str(w.message) for w in caught if issubclass(w.category, UserWarning)], cache


def _shape(scene, name):
    return next(s for s in scene.shapes if s.name == name)


def test_scene_name_and_groups(imported):
    scene, _, _ = imported
    assert scene.name == "test_scene"  # the stem, sanitised
    assert set(scene.group_names) == {"ceiling", "lamp", "world"}
    assert all(g.emission == "flat" for g in scene.light_groups)
    assert _shape(scene, "Panel").emitter.group == "ceiling"  # by collection
    bulb = next(li for li in scene.lights if li.name == "Bulb")
    assert bulb.type == "point" and bulb.group == "lamp"  # by the illumix_group property
    assert bulb.position == pytest.approx((1.0, -1.0, 1.5))
    assert bulb.strength == pytest.approx(50.0 / (4 * math.pi))  # W -> W/sr
    sky = next(li for li in scene.lights if li.type == "constant")
    assert sky.group == "world" and sky.strength == pytest.approx(0.02, rel=1e-5)


def test_view_matches_camera(imported):
    scene, _, _ = imported
    (v,) = scene.views
    assert v.name == "Camera" and v.resolution == (64, 48)  # 128 x 96 at 50 %
    assert v.fov == pytest.approx(math.degrees(2 * math.atan(18 / 35)))  # 36 mm sensor, 35 mm lens, fit width
    assert v.origin == pytest.approx((0.0, -4.0, 1.5))
    t = math.radians(75)  # the camera's X rotation: -Z turns to (0, sin t, -cos t), +Y to (0, cos t, sin t)
    assert np.subtract(v.target, v.origin) == pytest.approx((0, math.sin(t), -math.cos(t)), abs=1e-6)
    assert v.up == pytest.approx((0, math.cos(t), math.sin(t)), abs=1e-6)


def test_measured_reflectance(imported):
    from illumix.retarget.reflectances import get_reflectances

    scene, _, _ = imported
    cube = _shape(scene, "Cube")
    m = scene.materials[cube.material]
    assert m.reflectance == LibrarySpectrum(library="ColorChecker N Ohta", sample="red")
    names, r = get_reflectances("ColorChecker N Ohta", scene.spectral_grid)
    np.testing.assert_allclose(scene.spectrum(m.reflectance, "cube"), r[names.index("red")])


def test_upsampled_colour_roundtrips(imported):
    """The sphere's Diffuse colour (0.05, 0.1, 0.6) linear sRGB comes back from its spectrum under D65.

    Tolerance 0.002 per channel: the Jakob 2019 fit itself is off by ~2e-4 (ΔE2000 ~ 0.02), the
    renderer's 5 nm band averages on 395-705 nm by ~3e-4; fitting under the wrong white (equal
    energy instead of D65) would be off by ~0.02, ten times the tolerance."""
    import colour

    scene, _, _ = imported
    m = scene.materials[_shape(scene, "Sphere").material]
    assert m.kind == "diffuse" and isinstance(m.reflectance, TableSpectrum)
    assert 0 <= min(m.reflectance.values) and max(m.reflectance.values) <= 1
    shape = colour.SpectralShape(380, 780, 5)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)

    def srgb(wl, values):
        sd = colour.SpectralDistribution(dict(zip(shape.wavelengths, np.interp(shape.wavelengths, wl, values))))
        xyz = colour.sd_to_XYZ(sd, cmfs, d65, method="Integration") / 100
        return colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)

    want = (0.05, 0.1, 0.6)
    assert srgb(m.reflectance.wavelengths, m.reflectance.values) == pytest.approx(want, abs=2e-3)
    bands = scene.spectrum(m.reflectance, "sphere")  # what the renderer uses
    assert srgb(scene.spectral_grid.wavelengths, bands) == pytest.approx(want, abs=2e-3)


def test_materials_kinds(imported):
    scene, _, _ = imported
    floor = scene.materials[_shape(scene, "Floor").material]
    assert floor.kind == "roughplastic" and floor.alpha == pytest.approx(0.25)  # roughness 0.5 squared
    # A grey upsamples to a flat spectrum, divided by the rough-plastic scale that keeps Blender's look
    from illumix.scene.plastic_scale import plastic_diffuse_scale

    assert np.allclose(floor.reflectance.values, 0.5 / plastic_diffuse_scale(0.25, floor.int_ior), atol=3e-3)


def test_texture_linked_colour_warns(imported):
    scene, messages, _ = imported
    hits = [m for m in messages if "Speckled" in m and "Noise Texture" in m]
    assert hits and "Base Color" in hits[0] and "[0.8, 0.8, 0.8]" in hits[0]  # says what it used instead
    assert "Vase" in [s.name for s in scene.shapes]


def test_area_light_power(imported):
    scene, _, _ = imported
    panel = _shape(scene, "Panel")
    assert panel.type == "rectangle" and panel.material is None
    t = panel.transform.to_matrix()
    area = 4 * np.linalg.norm(np.cross(t[:3, 0], t[:3, 1]))  # the rectangle is [-1, 1]^2
    assert area == pytest.approx(1.0 * 0.5)
    assert panel.emitter.strength * area * math.pi == pytest.approx(100.0)  # radiance x A x pi = power
    normal = np.linalg.inv(t[:3, :3]).T @ [0, 0, 1]
    assert normal / np.linalg.norm(normal) == pytest.approx((0, 0, -1))  # emits down, as Blender's -Z
    assert t[:3, 3] == pytest.approx((0, 0, 2.5))


def _read_ply(path: Path):
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode("ascii").split("\n")
    nv = int(next(h for h in head if h.startswith("element vertex")).split()[-1])
    nf = int(next(h for h in head if h.startswith("element face")).split()[-1])
    v = np.frombuffer(data, "<f4", nv * 6, end).reshape(nv, 6)
    f = np.frombuffer(data, [("n", "u1"), ("i", "<i4", (3,))], nf, end + nv * 24)
    assert len(data) == end + nv * 24 + nf * 13 and np.all(f["n"] == 3)
    return v[:, :3], v[:, 3:], f["i"]


def test_meshes_world_space(imported):
    scene, _, cache = imported
    cube = _shape(scene, "Cube")
    assert cube.type == "ply" and Path(cube.filename).parent.parent == cache.resolve()
    pos, nrm, tri = _read_ply(Path(cube.filename))
    assert (len(pos), len(tri)) == (24, 12)  # flat shading: 4 vertices of its own per face
    assert pos[:, 2].min() == pytest.approx(0.0, abs=1e-6) and pos[:, 2].max() == pytest.approx(0.6, abs=1e-6)
    face_n = np.cross(pos[tri[:, 1]] - pos[tri[:, 0]], pos[tri[:, 2]] - pos[tri[:, 0]])
    assert np.all(np.einsum("ij,ij->i", face_n, nrm[tri].mean(axis=1)) > 0)  # winding agrees with normals
    pos, nrm, tri = _read_ply(Path(_shape(scene, "Sphere").filename))
    assert len(tri) == 3840  # the Subdivision modifier at its render level (2) is applied
    assert np.linalg.norm(nrm, axis=1) == pytest.approx(1.0, abs=1e-5)


def test_cache_reused(blend, imported):
    _, _, cache = imported
    before = (cache / "scene.json").stat().st_mtime_ns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again = blend_import.load_blend(blend, cache_dir=cache)[0]
    assert (cache / "scene.json").stat().st_mtime_ns == before
    assert again.scene_hash == imported[0].scene_hash


def test_the_cli_loads_a_blend_file_by_its_extension(blend, tmp_path, monkeypatch):
    from illumix.scene_files import load_scene_file as load_scenes

    monkeypatch.setenv("ILLUMIX_CACHE", str(tmp_path / "cache"))
    upper = tmp_path / "Upper.BLEND"  # the suffix is matched case-insensitively
    upper.write_bytes(blend.read_bytes())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (scene,) = load_scenes(upper)
    assert scene.name == "Upper"
    (entry,) = (tmp_path / "cache" / "blend-import").iterdir()  # <sha256[:16]>/ and no temporary left over
    assert len(entry.name) == 16 and (entry / "scene.json").is_file()


def _one_line_error(path, **kw) -> str:
    with pytest.raises(SceneError) as exc:
        blend_import.load_blend(path, **kw)
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_errors(tmp_path):
    assert "does not exist" in _one_line_error(tmp_path / "missing.blend")
    bad = tmp_path / "bad.blend"
    bad.write_bytes(b"not a blend file at all")
    assert "cannot import" in _one_line_error(bad, cache_dir=tmp_path / "c1")
    nocam = _make(tmp_path / "nocam.blend", "--no-camera")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        msg = _one_line_error(nocam, cache_dir=tmp_path / "c2")
    assert "has no (perspective) camera; add one" in msg and "nocam.blend" in msg


def test_reflectance_names():
    assert blend_import.resolve_reflectance("red", "m") == {"library": "ColorChecker N Ohta", "sample": "red"}
    assert blend_import.resolve_reflectance("CQS 9.0/VS3", "m") == {"library": "CQS 9.0", "sample": "VS3"}
    with pytest.raises(SceneError, match="did you mean.*'red'"):
        blend_import.resolve_reflectance("rde", "materials 'x'")


def test_sanitize():
    assert blend_import.sanitize("My Lamp #2") == "My_Lamp_2"
    assert blend_import.sanitize("..hidden..name") == "hidden.name"
    assert blend_import.sanitize("???", "group") == "group"
