"""``illumix render`` / ``illumix validate`` and the job runner: store contents, resume, bad configs,
executors (local pool, Ray on a local instance bound to 127.0.0.1)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from cli_testutil import run_cli
from illumix.renderer_jobs import jobs
from illumix.renderer_jobs.execute import execute
from illumix.scene.demo import demo_room_dict
from illumix.scene.load import scene_from_dict

TINY = ["--resolution", "24x16", "--spp", "16"]
needs_mitsuba = pytest.mark.skipif(__import__("importlib").util.find_spec("mitsuba") is None,
                                   reason="rendering needs the optional extra illumix[render]")


def tiny_scene_file(tmp_path, name="mini") -> str:
    """A small scene with two groups (a lamp panel and a point light) and two views."""
    d = {
        "name": name,
        "materials": {"grey": {"kind": "diffuse", "reflectance": {"value": 0.5}},
                      "cc": {"kind": "diffuse", "reflectance": {"library": "ColorChecker N Ohta", "sample": "red"}}},
        "shapes": [
            {"name": "floor", "type": "rectangle", "material": "grey",
             "transform": {"scale": 2, "rotate": [{"axis": [1, 0, 0], "angle": -90}]}},
            {"name": "ball", "type": "sphere", "material": "cc", "center": [0, 0.4, 0], "radius": 0.4},
            {"name": "panel", "type": "rectangle", "emitter": {"group": "lamp", "strength": 5},
             "transform": {"scale": 0.3, "rotate": [{"axis": [1, 0, 0], "angle": 90}], "translate": [0, 2, 0]}},
        ],
        "lights": [{"name": "bulb", "type": "point", "group": "bulb", "position": [1, 1, 1], "strength": 2}],
        "views": [{"name": "a", "origin": [0, 1, 3], "target": [0, 0.3, 0], "resolution": [20, 14]},
                  {"name": "b", "origin": [2, 1.5, 2], "target": [0, 0.3, 0], "resolution": [20, 14]}],
        "max_depth": 4,
    }
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump(d))
    return str(p)


@needs_mitsuba
def test_render_demo_then_nothing_to_do(tmp_path, capsys):
    from illumix.store import CubeStore

    store = str(tmp_path / "st")
    code, out, err = run_cli(capsys, "render", "--demo", "--store", store, *TINY, "--json")
    assert code == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["cubes_to_render"] == 6 and len(summary["rendered"]) == 8  # 2 views × 3 groups + 2 views
    st = CubeStore.open(store, mode="r")
    scene = st.scenes()[0]
    assert scene == "demo-room-0" and sorted(st.views(scene)) == ["corner", "front"]
    for view in st.views(scene):
        vm = st.view_meta(scene, view)
        assert (vm.width, vm.height) == (24, 16) and vm.groups == ["daylight", "ceiling", "desk"]
        assert set(vm.aovs) >= {"albedo", "albedo_bands", "normal", "depth", "mask"}
        assert st.read_aov(scene, view, "albedo_bands").shape == (16, 24, 63)
        for g in ("daylight", "ceiling", "desk"):
            assert st.is_complete(scene, view, g)
            meta = st.cube_meta(scene, view, g)
            assert meta.spp == 16 and meta.seed == 0 and meta.emission_name == "flat"
            assert meta.renderer.name == "mitsuba" and meta.renderer.variant.endswith("spectral")
            assert meta.scene_hash and len(meta.emission) == 63
            cube = st.read_cube(scene, view, g)
            assert cube.shape == (16, 24, 63) and np.all(np.isfinite(cube))
            # the default stores denoised copies (issue 15), made from the view's AOVs
            assert meta.denoised.method == "dt-irradiance" and meta.denoised.cost_ms >= 0
            assert meta.denoised.model_extra["guide_passes"]["direct"]["samples_per_pixel"] > 0
            # targeted extra paths (default x8 where the denoiser cannot reach), recorded
            tp = meta.render_stats["targeted_paths"]
            assert 0 < tp["pixels"] < 24 * 16 and tp["paths_per_pixel"] == 8 * 16  # some pixels, not all
            assert meta.renderer.settings["targeted_paths"]["spp_factor"] == 8
            for kind in ("transport", "illumination"):
                dn = st.read_cube(scene, view, g, kind=kind, denoised=True)
                assert dn.shape == cube.shape and np.all(np.isfinite(dn))
    assert summary["denoise"] == "dt-irradiance"
    code, out, err = run_cli(capsys, "render", "--demo", "--store", store, *TINY, "--json")
    assert code == 0 and json.loads(out.strip().splitlines()[-1])["rendered"] == []
    assert "nothing to do" in err


@needs_mitsuba
def test_resume_renders_only_missing_cubes(tmp_path, capsys):
    cfg = tiny_scene_file(tmp_path)
    store = str(tmp_path / "st")
    code, out, err = run_cli(capsys, "render", cfg, "--store", store, "--spp", "16", "--groups", "lamp", "--json")
    assert code == 0, err
    first = json.loads(out.strip().splitlines()[-1])["rendered"]
    assert sorted(first) == ["mini/a/[view+aovs]", "mini/a/lamp", "mini/b/[view+aovs]", "mini/b/lamp"]
    # an "interrupted" run: the bulb cubes are missing; the next run renders exactly those
    code, out, err = run_cli(capsys, "render", cfg, "--store", store, "--spp", "16", "--json")
    assert code == 0, err
    assert sorted(json.loads(out.strip().splitlines()[-1])["rendered"]) == ["mini/a/bulb", "mini/b/bulb"]
    # same description at another resolution: refused (one line, exit 2), nothing rendered
    code, out, err = run_cli(capsys, "render", cfg, "--store", store, "--resolution", "30x20")
    assert code == 2 and err.count("\n") == 1 and "30x20" in err and "--overwrite" in err
    # --overwrite replaces the view whole (every group, whatever --groups says)
    code, out, err = run_cli(capsys, "render", cfg, "--store", store, "--resolution", "30x20", "--views", "a",
                             "--groups", "bulb", "--overwrite", "--spp", "16", "--json")
    assert code == 0, err
    assert sorted(json.loads(out.strip().splitlines()[-1])["rendered"]) == [
        "mini/a/[view+aovs]", "mini/a/bulb", "mini/a/lamp"]
    from illumix.store import CubeStore

    st = CubeStore.open(store, mode="r")
    assert st.read_cube("mini", "a", "lamp").shape == (20, 30, 63)
    assert st.read_cube("mini", "b", "lamp").shape == (14, 20, 63)


@needs_mitsuba
def test_changed_description_is_a_conflict(tmp_path, capsys):
    cfg = tiny_scene_file(tmp_path)
    store = str(tmp_path / "st")
    assert run_cli(capsys, "render", cfg, "--store", store, "--spp", "16", "--views", "a", "--groups", "bulb")[0] == 0
    d = yaml.safe_load(open(cfg))
    d["materials"]["grey"]["reflectance"]["value"] = 0.3
    open(cfg, "w").write(yaml.safe_dump(d))
    code, out, err = run_cli(capsys, "render", cfg, "--store", store, "--spp", "16")
    assert code == 2 and "different scene description" in err and err.count("\n") == 1
    code, out, err = run_cli(capsys, "render", cfg, "--store", store, "--spp", "16", "--overwrite",
                             "--views", "a", "--groups", "bulb")
    assert code == 0, err


@pytest.mark.parametrize("argv, needle", [
    (["render", "--demo", "--resolution", "24x"], "resolution"),
    (["render", "--demo", "--spp", "8", "--wavelengths", "stratified"], "spp"),
    (["render", "--demo", "--spp", "48", "--sampler", "ldsampler"], "a power of 2"),
    (["render", "--demo", "--sampler", "sobol"], "pixel sampler"),
    (["render", "--demo", "--adaptive"], "need wavelengths 'stratified'"),
    (["render", "--demo", "--groups", "nope"], "no light group 'nope'"),
    (["render", "--demo", "--views", "nope"], "no view 'nope'"),
    (["render", "--demo", "--executor", "slurm"], "executor"),
    (["render", "--demo", "--noise-target", "5"], "--noise-target 5.0 must lie in (0, 1)"),
    (["render", "--demo", "--denoise", "dt-guide"], "did you mean 'dt-guides'"),
    (["render", "--demo", "--boost-factor", "0"], "boost factor 0 must be a whole number >= 1"),
    (["render", "--demo", "--boost-factor", "4", "--denoise", "none"], "use --boost-factor 1"),
    (["render", "--demo", "--boost-reach", "1.5"], "boost reach 1.5 must lie in (0, 1]"),
    (["render", "--demo", "--boost-factor", "1", "--boost-reach", "0.5"], "--boost-reach chooses where"),
    (["render", "--demo", "--denoise", "none", "--boost-reach", "0.5"], "drop it"),
    (["render"], "either a scene file"),
])
def test_bad_arguments_exit_2_and_write_nothing(tmp_path, capsys, argv, needle):
    store = tmp_path / "st"
    code, out, err = run_cli(capsys, *argv, "--store", str(store))
    assert code == 2 and needle in err and err.count("\n") == 1 and err.startswith("illumix: error:")
    assert not store.exists()


def test_bad_config_file_exit_2_and_write_nothing(tmp_path, capsys):
    cfg = tmp_path / "bad.yaml"
    d = yaml.safe_load(open(tiny_scene_file(tmp_path)))
    d["shapes"][1]["radius"] = 0
    cfg.write_text(yaml.safe_dump(d))
    store = tmp_path / "st"
    code, out, err = run_cli(capsys, "render", str(cfg), "--store", str(store))
    assert code == 2 and "shapes[1] (ball).radius" in err and err.count("\n") == 1
    assert not store.exists()
    cfg.write_text("name: [\n")
    code, out, err = run_cli(capsys, "render", str(cfg), "--store", str(store))
    assert code == 2 and "not valid YAML" in err and not store.exists()


def test_plan_lists_jobs_views_first(tmp_path):
    scene = scene_from_dict(yaml.safe_load(open(tiny_scene_file(tmp_path))))
    p = jobs.plan([scene], str(tmp_path / "none"))
    assert [j.label for j in p.view_jobs] == ["mini/a/[view+aovs]", "mini/b/[view+aovs]"]
    assert len(p.cube_jobs) == 4 and not p.skipped and not p.conflicts
    assert jobs.parse_resolution("32x24") == (32, 24)
    small = jobs.apply_resolution(scene, (8, 6))
    assert all(v.resolution == (8, 6) for v in small.views) and small.scene_hash == scene.scene_hash


@needs_mitsuba
def test_validate_cli_writes_validation_json(tmp_path, capsys):
    out_dir = tmp_path / "val"
    code, out, err = run_cli(capsys, "validate", "--out", str(out_dir), "--illuminants", "D65,A",
                             "--spp", "16", "--resolution", "96x64", "--json")
    assert code == 0, err
    doc = json.loads((out_dir / "validation.json").read_text())
    assert len(doc["patches"]) == 48 and [s["illuminant"] for s in doc["summary"]] == ["D65", "A"]
    p = doc["patches"][0]
    assert set(p) >= {"illuminant", "patch", "delta_e00", "relative_rg_bg_pct", "angular_deg"}
    assert all(s["max_delta_e00"] < 1e-3 for s in doc["summary"])
    code, out, err = run_cli(capsys, "validate", "--out", str(out_dir), "--illuminants", "D65,XX99")
    assert code == 2 and "XX99" in err
    code, out, err = run_cli(capsys, "validate", "--out", str(out_dir), "--resolution", "12x8")
    assert code == 2 and "higher resolution" in err


@needs_mitsuba
def test_local_process_pool(tmp_path):
    """Two spawned worker processes render the tiny scene into one store."""
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.store import CubeStore

    scene = scene_from_dict(yaml.safe_load(open(tiny_scene_file(tmp_path))))
    store = str(tmp_path / "st")
    p = jobs.plan([scene], store)
    res = execute(p, store, RenderSettings(spp=16), executor="local", workers=2)
    assert len(res) == 6
    st = CubeStore.open(store, mode="r")
    assert all(st.is_complete("mini", v, g) for v in ("a", "b") for g in ("lamp", "bulb"))
    # Reproducible whatever the process and thread layout: in-process (all threads) gives the same bits.
    solo = str(tmp_path / "solo")
    execute(jobs.plan([scene], solo, views=["a"]), solo, RenderSettings(spp=16), executor="local", workers=1)
    one = CubeStore.open(solo, mode="r")
    assert all(np.array_equal(st.read_cube("mini", "a", g), one.read_cube("mini", "a", g)) for g in ("lamp", "bulb"))


@needs_mitsuba
def test_ray_executor_on_local_instance(tmp_path):
    """A local Ray instance (127.0.0.1 only, started here) renders the jobs; the cubes equal the
    in-process render of the same seed."""
    ray = pytest.importorskip("ray")
    from illumix.renderer_jobs.mitsuba.render import RenderSettings, render_cube
    from illumix.store import CubeStore

    scene = scene_from_dict(yaml.safe_load(open(tiny_scene_file(tmp_path))), base=tmp_path)
    store = str(tmp_path / "st")
    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1", log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": str(__import__("pathlib").Path(__file__).parents[1])}})
    try:
        p = jobs.plan([scene], store)
        # (boost_factor=1: the in-process render below has no guides to choose targeted extra paths from)
        res = execute(p, store, RenderSettings(spp=16, seed=5, boost_factor=1), executor="ray")
        assert len(res) == 6
    finally:
        ray.shutdown()
    st = CubeStore.open(store, mode="r")
    got = st.read_cube("mini", "a", "lamp")
    ref = render_cube(scene, "a", "lamp", RenderSettings(spp=16, seed=5)).cube
    meta = st.cube_meta("mini", "a", "lamp")
    np.testing.assert_allclose(got, ref, rtol=max(meta.storage.rel_error_bound, 1e-7) * 1.01, atol=0)


def test_demo_room_dict_serialises():
    json.dumps(demo_room_dict(1), default=list)


@needs_mitsuba
def test_new_store_in_empty_dir_or_fsspec_url(tmp_path, capsys):
    """A store is created where none is yet: an empty directory, an fsspec URL with nothing there.
    A directory holding something else is refused with one line, before anything is rendered."""
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.store import CubeStore

    scene_file = tiny_scene_file(tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    code, out, err = run_cli(capsys, "render", scene_file, "--store", str(empty), *TINY)
    assert code == 0, err
    assert CubeStore.open(str(empty), mode="r").is_complete("mini", "a", "lamp")

    url = f"memory://illumix-test-{tmp_path.name}"
    assert not CubeStore.exists(url)
    scene = scene_from_dict(yaml.safe_load(open(scene_file)))
    p = jobs.plan([scene], url, views=["a"], groups=["lamp"])
    execute(p, url, RenderSettings(spp=16), executor="local", workers=1)
    assert CubeStore.exists(url) and CubeStore.open(url, mode="r").is_complete("mini", "a", "lamp")

    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("not a store")
    code, out, err = run_cli(capsys, "render", scene_file, "--store", str(other), *TINY)
    assert code == 2 and err.count("\n") == 1 and "is not empty and is not an illumix store" in err
    assert sorted(x.name for x in other.iterdir()) == ["notes.txt"]


def test_plan_refuses_an_unreadable_store_instead_of_planning_it_empty(tmp_path):
    """Issue 34: the planner once answered None/[] on any exception, so a damaged view was planned
    as missing and rendered again over the damage; now only "not there yet" is missing."""
    from illumix.store import CubeStore, StoreError

    scene = scene_from_dict(yaml.safe_load(open(tiny_scene_file(tmp_path))))
    path = tmp_path / "st"
    st = CubeStore.open(str(path), mode="a")
    st.write_view("mini", "a", jobs._view_meta(scene, "a"))
    p = jobs.plan([scene], str(path))
    assert "mini/a/[view+aovs]" in [j.label for j in p.skipped]  # the view is stored; the others are to do
    meta = next(path.glob("scenes/mini/a/zarr.json"))
    meta.write_text(meta.read_text()[: len(meta.read_text()) // 2])
    with pytest.raises(StoreError):
        jobs.plan([scene], str(path))
