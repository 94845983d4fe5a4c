"""``illumix dataset CONFIG --store``: config validation (one line naming the field), a tiny dataset of
generated rooms rendered into a store, resume (a rerun renders nothing and generates nothing), the
generator's version and seed in every cube's metadata, ``--dry-run``, and keep-going job execution.

Rendering settings are the cheapest that still go through every step (4-wavelength paths, no
illumination cube, no denoised copy, no dark probe): a cold Dr.Jit kernel cache costs seconds per
(room, group); the all-bands default compiles 10-25 s per kernel on 2 cores.
"""

from __future__ import annotations

import json

import pytest
import yaml

from cli_testutil import run_cli
from test_cli_spectra import assert_one_line_error

needs_mitsuba = pytest.mark.skipif(__import__("importlib").util.find_spec("mitsuba") is None,
                                   reason="rendering needs the optional extra illumix[render]")

GEN = {"probe": False, "views": [1, 1], "resolution": [16, 12]}
RENDER = {"spp": 16, "workers": 1, "wavelengths": "stratified", "denoise": "none", "illumination": False,
          "skip_dark": False}


def write_config(tmp_path, doc, name="ds.yaml") -> str:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(doc))
    return str(p)


def tiny(**over) -> dict:
    doc = {"name": "tiny", "generated": {"count": 2, "seed": 3, "generator": dict(GEN)}, "render": dict(RENDER)}
    doc.update(over)
    return doc


@pytest.mark.parametrize("doc, names", [
    ({"generated": {"count": 1}}, "name: required"),
    ({"name": "x"}, "no scenes"),
    ({"name": "x", "generated": {"count": -1}}, "generated.count"),
    ({"name": "x", "generated": {"count": 1, "generator": {"windows": [2, 5]}}}, "generated.generator: windows"),
    ({"name": "x", "generated": {"count": 1, "generator": {"layouts": ["round"]}}}, "layouts: unknown ['round']"),
    ({"name": "x", "generated": {"count": 1, "generatr": {}}}, "unknown field 'generatr' in generated"),
    ({"name": "x", "generated": {"count": 1}, "render": {"sppp": 16}}, "unknown field 'sppp' in render"),
    ({"name": "x", "generated": {"count": 1}, "render": {"spp": 0}}, "render.spp"),
    ({"name": "x", "generated": {"count": 1}, "render": {"workers": "two"}}, "render.workers"),
    ({"name": "x", "generated": {"count": 1}, "render": {"address": "1.2.3.4:6379"}},
     "render.address is for render.executor ray"),
    ({"name": "x", "generated": {"count": 1}, "render": {"executor": "slurm"}}, "render.executor: unknown executor"),
    ({"name": "x", "generated": {"count": 1}, "render": {"wavelengths": "strat"}}, "render: unknown wavelength"),
    ({"name": "x", "generated": {"count": 1}, "render": {"noise_target": 2.0, "wavelengths": "stratified"}},
     "render.noise_target 2.0 must lie in (0, 1)"),
    ({"name": "x", "generated": {"count": 1}, "render": {"resolution": "big"}}, "render.resolution"),
    ({"name": "x", "generated": {"count": 1}, "render": {"boost_factor": True}}, "render.boost_factor"),
    ({"name": "x", "generated": {"count": 1}, "render": {"boost_factor": 1, "boost_reach": 0.5}},
     "render.boost_reach chooses where the targeted extra paths go"),
    ({"name": "x", "scenes": ["missing.yaml"]}, "scenes: missing.yaml"),
    ([1, 2], "a dataset config is a mapping"),
])
def test_a_bad_config_is_one_line_naming_the_field(tmp_path, capsys, doc, names):
    store = tmp_path / "st"
    line = assert_one_line_error(*run_cli(capsys, "dataset", write_config(tmp_path, doc), "--store", str(store)))
    assert names in line, line
    assert not store.exists() or not (store / ".illumix-scenes").exists()


def test_unreadable_configs(tmp_path, capsys):
    line = assert_one_line_error(*run_cli(capsys, "dataset", str(tmp_path / "nope.yaml"), "--store", str(tmp_path)))
    assert "does not exist" in line
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: [unclosed\n")
    assert "not valid YAML" in assert_one_line_error(*run_cli(capsys, "dataset", str(bad), "--store",
                                                              str(tmp_path / "st")))


def test_a_scene_named_twice_is_refused(tmp_path, capsys):
    from illumix.scene.load import dump_scene
    from illumix.scenegen.generate import GeneratorConfig, generate_scene

    dump_scene(generate_scene(3, GeneratorConfig(**GEN)), tmp_path / "dup.yaml")  # also room-000003
    cfg = write_config(tmp_path, tiny(scenes=["dup.yaml"]))
    line = assert_one_line_error(*run_cli(capsys, "dataset", cfg, "--store", str(tmp_path / "st"), "--dry-run"))
    assert "two scenes are named 'room-000003'" in line


@needs_mitsuba
def test_tiny_dataset_renders_resumes_and_records_the_generator(tmp_path, capsys):
    from illumix.scenegen import GENERATOR_VERSION
    from illumix.store import CubeStore

    cfg = write_config(tmp_path, tiny())
    store = tmp_path / "st"
    # --dry-run: plans (generating in memory), writes nothing
    code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(store), "--dry-run", "--json")
    assert code == 0, err
    plan = json.loads(out.strip().splitlines()[-1])
    assert plan["dry_run"] and plan["scenes"] == 2 and plan["views"] == 2 and plan["cubes_skipped"] == 0
    assert plan["cubes_planned"] >= 4 and len(plan["jobs"]) == plan["cubes_planned"] + 2
    assert {j.split("/")[0] for j in plan["jobs"]} == {"room-000003", "room-000004"}
    assert not store.exists()

    code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(store), "--json")
    assert code == 0, err
    s = json.loads(out.strip().splitlines()[-1])
    assert s["rooms_generated"] == 2 and s["rooms_cached"] == 0 and s["failed"] == []
    assert s["cubes_rendered"] + s["cubes_empty"] == plan["cubes_planned"] and s["views_written"] == 2
    assert s["wall_s"] > 0 and s["cpu_s"] > 0 and s["cube_mean_s"] > 0 and s["generator_version"] == GENERATOR_VERSION
    cached = sorted(p.name for p in (store / ".illumix-scenes").iterdir())
    assert cached == ["room-000003.yaml", "room-000004.yaml"]

    st = CubeStore.open(str(store), mode="r")
    assert st.scenes() == ["room-000003", "room-000004"]
    for seed, scene in ((3, "room-000003"), (4, "room-000004")):
        vm = st.view_meta(scene, "view0")
        assert (vm.width, vm.height) == (16, 12)
        for g in vm.groups:
            assert st.is_complete(scene, "view0", g)
            meta = st.cube_meta(scene, "view0", g)
            assert meta.generator == {"name": "illumix.scenegen", "version": GENERATOR_VERSION, "seed": seed}
            assert meta.spp == 16

    # rerun: nothing generated, nothing rendered
    mtimes = {p.name: p.stat().st_mtime_ns for p in (store / ".illumix-scenes").iterdir()}
    code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(store), "--json")
    assert code == 0, err
    again = json.loads(out.strip().splitlines()[-1])
    assert again["rooms_cached"] == 2 and again["rooms_generated"] == 0
    assert again["cubes_planned"] == 0 and again["cubes_rendered"] == 0
    assert again["cubes_skipped"] == plan["cubes_planned"] and "nothing to do" in err
    assert mtimes == {p.name: p.stat().st_mtime_ns for p in (store / ".illumix-scenes").iterdir()}

    # a bigger count renders only the new room (--limit caps it); dry run leaves the cache alone
    cfg3 = write_config(tmp_path, tiny(generated={"count": 3, "seed": 3, "generator": dict(GEN)}), "ds3.yaml")
    code, out, err = run_cli(capsys, "dataset", cfg3, "--store", str(store), "--dry-run", "--json", "--limit", "2")
    assert code == 0 and json.loads(out.strip().splitlines()[-1])["jobs"] == []
    code, out, err = run_cli(capsys, "dataset", cfg3, "--store", str(store), "--dry-run", "--json")
    third = json.loads(out.strip().splitlines()[-1])
    assert code == 0 and third["rooms_cached"] == 2 and third["rooms_generated"] == 1
    assert {j.split("/")[0] for j in third["jobs"]} == {"room-000005"}
    assert not (store / ".illumix-scenes" / "room-000005.yaml").exists()


def test_room_cache_regenerates_on_another_version_or_config(tmp_path):
    from illumix import scene_corpus
    from illumix.scenegen.generate import GeneratorConfig

    gen = GeneratorConfig(**GEN)
    scene, status = scene_corpus.room(11, gen, tmp_path)
    path = tmp_path / "room-000011.yaml"
    assert status == "generated" and path.read_text().startswith("# illumix.scenegen version=")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary file left
    again, status = scene_corpus.room(11, gen, tmp_path)
    assert status == "cached" and again.scene_hash == scene.scene_hash
    # another config (or a file from another generator version): generated again
    other, status = scene_corpus.room(11, gen.model_copy(update={"resolution": (20, 15)}), tmp_path)
    assert status == "regenerated" and other.views[0].width == 20
    path.write_text(path.read_text().replace("version=", "version=0", 1))
    assert scene_corpus.room(11, gen, tmp_path)[1] == "regenerated"
    path.write_text("# illumix.scenegen garbage\n")
    assert scene_corpus.room(11, gen, tmp_path)[1] == "regenerated"


def test_keep_going_reports_failures_and_runs_the_rest(tmp_path, monkeypatch):
    """A failed view job fails its cubes without running them; other jobs go on (local executor)."""
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.scene.demo import demo_room
    from illumix.renderer_jobs.mitsuba.render import RenderSettings

    scene = demo_room(0, resolution=(8, 6))
    p = jobs.plan([scene], str(tmp_path / "st"))
    ran = []

    def fake_run_job(payload, job, store_path, settings_dict, threads=None, overwrite=False):
        ran.append(job.label)
        if job.view == "front" and job.group is None or job.group == "desk":
            raise RuntimeError("boom")
        return {"job": job.label, "seconds": 0.0, "kind": "view" if job.group is None else "cube"}

    monkeypatch.setattr(jobs, "run_job", fake_run_job)
    seen = []
    results = execute(p, str(tmp_path / "st"), RenderSettings(), keep_going=True,
                           on_done=lambda job, r, exc: seen.append((job.label, exc is None)))
    failed = sorted(label for label, ok in seen if not ok)
    assert failed == ["demo-room-0/corner/desk", "demo-room-0/front/[view+aovs]", "demo-room-0/front/ceiling",
                      "demo-room-0/front/daylight", "demo-room-0/front/desk"]
    assert not [r for r in ran if r.startswith("demo-room-0/front/") and not r.endswith("[view+aovs]")]
    assert sorted(r["job"] for r in results) == ["demo-room-0/corner/[view+aovs]", "demo-room-0/corner/ceiling",
                                                 "demo-room-0/corner/daylight"]
    with pytest.raises(jobs.JobError, match="boom"):  # the default stops at the first failure
        execute(p, str(tmp_path / "st"), RenderSettings())


def test_room_generation_prints_a_line_per_room_off_a_terminal(tmp_path, monkeypatch):
    """Logs and CI see the rooms being generated (issue 38: "rooms: 1 generated" for 25 minutes and
    nothing before): one plain line per room when stderr is not a terminal; none in a dry run."""
    import io
    from pathlib import Path

    from rich.console import Console

    from illumix import cmd_dataset
    from illumix.dataset_config import load_config

    cfg_path = Path(write_config(tmp_path, {"name": "tiny", "generated": {"count": 2, "seed": 3, "generator": dict(GEN)}}))
    out = io.StringIO()
    monkeypatch.setattr(cmd_dataset, "console", Console(file=out, force_terminal=False, width=200))
    cmd_dataset._corpus(load_config(cfg_path), cfg_path, tmp_path / "rooms", None, dry_run=False, quiet=False)
    lines = [ln for ln in out.getvalue().splitlines() if ln.startswith("[")]
    assert lines == ["[1/2] scene room-000003: generated", "[2/2] scene room-000004: generated"], out.getvalue()
    out.truncate(0)
    cmd_dataset._corpus(load_config(cfg_path), cfg_path, tmp_path / "rooms2", None, dry_run=True, quiet=False)
    assert not [ln for ln in out.getvalue().splitlines() if ln.startswith("[")]
