"""``illumix scenes generate`` (scene files ``illumix render`` accepts, resumable) and ``illumix scenes
preview`` (a contact sheet PNG of the expected size); bad inputs are one line, exit 2."""

from __future__ import annotations

import json

import pytest
import yaml

from cli_testutil import run_cli
from test_cli_spectra import assert_one_line_error

needs_mitsuba = pytest.mark.skipif(__import__("importlib").util.find_spec("mitsuba") is None,
                                   reason="rendering needs the optional extra illumix[render]")

GEN = {"views": [1, 2], "resolution": [16, 12], "probe": False}


@pytest.fixture(scope="module")
def rooms(tmp_path_factory):
    """A folder shared by the tests of this file, with a small generator config ``gen.yaml``."""
    root = tmp_path_factory.mktemp("rooms")
    (root / "gen.yaml").write_text(yaml.safe_dump(GEN))
    return root


def test_generate_writes_files_that_load_and_resumes(rooms, capsys):
    from illumix.scene.load import load_scenes
    from illumix.scenegen import GENERATOR_VERSION

    out = rooms / "out"
    code, stdout, err = run_cli(capsys, "scenes", "generate", "--count", "3", "--seed", "7", "--out", str(out),
                                "--config", str(rooms / "gen.yaml"), "--json")
    assert code == 0, err
    s = json.loads(stdout.strip().splitlines()[-1])
    assert s["generated"] == 3 and s["cached"] == 0 and s["generator_version"] == GENERATOR_VERSION
    assert sorted(p.name for p in out.iterdir()) == ["room-000007.yaml", "room-000008.yaml", "room-000009.yaml"]
    assert "3 room(s)" in err and "3 generated" in err
    for seed in (7, 8, 9):
        (scene,) = load_scenes(out / f"room-{seed:06d}.yaml")
        assert scene.name == f"room-{seed:06d}" and scene.generator["seed"] == seed
        assert 1 <= len(scene.views) <= 2 and (scene.views[0].width, scene.views[0].height) == (16, 12)
        assert 2 <= len(scene.group_names) <= 4
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    code, stdout, err = run_cli(capsys, "scenes", "generate", "--count", "3", "--seed", "7", "--out", str(out),
                                "--config", str(rooms / "gen.yaml"), "--json")
    assert code == 0, err
    assert json.loads(stdout.strip().splitlines()[-1])["cached"] == 3
    assert before == {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    # --no-probe on the command line and a dataset config as --config give the same rooms
    ds = rooms / "ds.yaml"
    ds.write_text(yaml.safe_dump({"name": "d", "generated": {"count": 1, "generator": {**GEN, "probe": True}}}))
    code, stdout, err = run_cli(capsys, "scenes", "generate", "--count", "1", "--seed", "7", "--out", str(out),
                                "--config", str(ds), "--no-probe", "--json")
    assert code == 0 and json.loads(stdout.strip().splitlines()[-1])["cached"] == 1, err


@needs_mitsuba
def test_render_accepts_a_generated_file(rooms, capsys):
    from illumix.store import CubeStore

    out = rooms / "single"
    code, _, err = run_cli(capsys, "scenes", "generate", "--count", "1", "--seed", "7", "--out", str(out),
                           "--config", str(rooms / "gen.yaml"))
    assert code == 0, err
    store = str(rooms / "st")
    code, _, err = run_cli(capsys, "render", str(out / "room-000007.yaml"), "--store", store, "--spp", "16",
                                "--wavelengths", "stratified", "--denoise", "none", "--no-illumination",
                                "--no-skip-dark", "--views", "view0", "--json")
    assert code == 0, err
    st = CubeStore.open(store, mode="r")
    assert st.scenes() == ["room-000007"]
    groups = st.view_meta("room-000007", "view0").groups
    assert all(st.is_complete("room-000007", "view0", g) for g in groups)
    assert st.cube_meta("room-000007", "view0", groups[0]).generator["seed"] == 7


@needs_mitsuba
def test_preview_writes_a_contact_sheet(rooms, capsys):
    import cv2

    src = rooms / "prev"
    code, _, err = run_cli(capsys, "scenes", "generate", "--count", "2", "--seed", "7", "--out", str(src),
                           "--config", str(rooms / "gen.yaml"))
    assert code == 0, err
    from illumix.scene.load import load_scenes

    n_views = [len(load_scenes(src / f"room-00000{s}.yaml")[0].views) for s in (7, 8)]
    sheet = rooms / "sheet.png"
    code, _, err = run_cli(capsys, "scenes", "preview", str(src / "room-000007.yaml"), str(src / "room-000008.yaml"),
                           "--out", str(sheet), "--spp", "4", "--size", "32x24")
    assert code == 0, err
    img = cv2.imread(str(sheet))
    # one scene per row, as many columns as the most views; each tile 32x24 under a 16 px label
    assert img.shape == (2 * (24 + 16), 32 * max(n_views), 3)
    assert img[16:40, :32].std() > 0  # something rendered in the first tile
    # a dataset config: its generated rooms (in memory), capped by --max-scenes
    cfg = rooms / "preview-ds.yaml"
    cfg.write_text(yaml.safe_dump({"name": "p", "generated": {"count": 5, "seed": 7, "generator": GEN}}))
    code, _, err = run_cli(capsys, "scenes", "preview", str(cfg), "--out", str(sheet), "--spp", "4",
                           "--size", "32x24", "--max-scenes", "1")
    assert code == 0, err
    assert cv2.imread(str(sheet)).shape == (24 + 16, 32 * n_views[0], 3)


@pytest.mark.parametrize("argv, says", [
    (["scenes", "generate", "--count", "0", "--seed", "1", "--out", "{tmp}/o"], "--count"),
    (["scenes", "generate", "--count", "2", "--seed", "999999", "--out", "{tmp}/o"], "must be <= 1000000"),
    (["scenes", "generate", "--count", "1", "--out", "{tmp}/file.txt"], "is a file"),
    (["scenes", "generate", "--count", "1", "--out", "{tmp}/o", "--config", "{tmp}/missing.yaml"], "does not exist"),
    (["scenes", "generate", "--count", "1", "--out", "{tmp}/o", "--config", "{tmp}/badgen.yaml"],
     "unknown field 'colour'"),
    (["scenes", "preview", "{tmp}/missing.yaml", "--out", "{tmp}/s.png"], "does not exist"),
    (["scenes", "preview", "{tmp}/file.txt", "--out", "{tmp}/s.jpg"], "give a .png file name"),
    (["scenes", "preview", "{tmp}/file.txt", "--out", "{tmp}/nowhere/s.png"], "does not exist"),
    (["scenes", "preview", "{tmp}/file.txt", "--out", "{tmp}/s.png", "--size", "huge"], "--size"),
    (["scenes", "preview", "{tmp}/badgen.yaml", "--out", "{tmp}/s.png"], "badgen.yaml"),
])
def test_bad_inputs_are_one_line(tmp_path, capsys, argv, says):
    (tmp_path / "file.txt").write_text("x")
    (tmp_path / "badgen.yaml").write_text(yaml.safe_dump({"colour": "red"}))
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    line = assert_one_line_error(*run_cli(capsys, *argv))
    assert says in line, line
    assert not (tmp_path / "o").exists() and not (tmp_path / "s.png").exists()
