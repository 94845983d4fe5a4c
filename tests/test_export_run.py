"""The export as a run: splits by scene, manifest checksums, resume after an interruption, atomic
files, and the command line's one-line errors (exit 2)."""

from __future__ import annotations

import json

import pytest
from cli_testutil import run_cli
from export_testutil import build_export_store
from test_cli_spectra import assert_one_line_error

pytest.importorskip("rawpy")


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return build_export_store(tmp_path_factory.mktemp("run") / "store")


def test_split_scenes_disjoint_and_seeded():
    from illumix.dataset_export.splits import split_counts, split_scenes

    scenes = [f"s{i}" for i in range(23)]
    a = split_scenes(scenes, (0.7, 0.15, 0.15), seed=5)
    assert a == split_scenes(reversed(scenes), (0.7, 0.15, 0.15), seed=5)  # order-free, seeded
    assert a != split_scenes(scenes, (0.7, 0.15, 0.15), seed=6)
    assert sorted(a) == sorted(scenes)
    assert [list(a.values()).count(s) for s in ("train", "val", "test")] == split_counts(23, (0.7, 0.15, 0.15))
    assert split_counts(3, (0.8, 0.1, 0.1)) == [1, 1, 1] and split_counts(2, (0.8, 0.1, 0.1)) == [2, 0, 0]


def test_places_split_by_scene(store, tmp_path):
    """Repeated views (count > views) stay in their scene's split; no scene in two splits."""
    from illumix.dataset_export.run import ExportOptions, export_dataset

    s = export_dataset(ExportOptions(store=store, out=str(tmp_path / "o"), count=9, seed=2,
                                     pairs="A,D65;FL11,D50", split=(0.5, 0.25, 0.25)))
    meta = json.loads((tmp_path / "o" / "Nikon-5100-NPL" / "meta.json").read_text())
    split = json.loads((tmp_path / "o" / "Nikon-5100-NPL" / "split.json").read_text())
    scene_split = {}
    for name, places in split.items():
        for p in places:
            assert scene_split.setdefault(meta[p]["Scene"], name) == name
    assert len(meta) == 9 and s["counts"]["places"] == 9 and len(set(scene_split.values())) == 3
    assert {tuple(i["name"] for i in e["Illuminants"]) for e in meta.values()} == {("A", "D65"), ("FL11", "D50")}


def test_resume_after_interruption(store, tmp_path):
    """Interrupted after two places, then rerun: the same files as one uninterrupted run; a damaged
    file is rewritten, a leftover temporary removed, and the manifest's checksums verify."""
    from illumix.dataset_export.journal import verify_manifest
    from illumix.dataset_export.run import ExportOptions, export_dataset

    opts = dict(store=store, seed=4, size=(32, 24))
    export_dataset(ExportOptions(out=str(tmp_path / "whole"), **opts))
    calls = []

    def stop(n, label):
        if label is not None:
            calls.append(label)
            if len(calls) == 2:
                raise KeyboardInterrupt

    part = tmp_path / "part"
    with pytest.raises(KeyboardInterrupt):
        export_dataset(ExportOptions(out=str(part), **opts), stop)
    assert not (part / "manifest.json").exists()
    done = sorted(p.relative_to(part) for p in part.rglob("*.tiff"))
    assert len(done) == 4
    (part / done[0]).write_bytes(b"damaged")
    (part / "Nikon-5100-NPL" / "x" ).mkdir()
    (part / "Nikon-5100-NPL" / "x" / ".y.illumix-tmp.tiff").write_bytes(b"half")
    export_dataset(ExportOptions(out=str(part), **opts))
    assert verify_manifest(part) == []
    assert not list(part.rglob("*.illumix-tmp*"))
    whole = json.loads((tmp_path / "whole" / "manifest.json").read_text())["files"]
    again = json.loads((part / "manifest.json").read_text())["files"]
    assert {k: v for k, v in whole.items() if k != "README.md"} == {k: v for k, v in again.items() if k != "README.md"}


def test_interrupted_write_leaves_no_file(tmp_path):
    from illumix.dataset_export.journal import Journal

    j = Journal(tmp_path, {"a": 1})

    def half(path):
        path.write_bytes(b"half")
        raise OSError("disk full")

    with pytest.raises(OSError):
        j.write("d/f.tiff", half)
    assert not (tmp_path / "d" / "f.tiff").exists() and not list(tmp_path.rglob("*.illumix-tmp*"))
    assert not j.complete("d/f.tiff")


@pytest.mark.parametrize("args, says", [
    (["--sensors", "Nikon 5100"], "did you mean 'Nikon 5100 (NPL)'"),
    (["--pairs", "A,D66"], "did you mean 'D65'"),
    (["--pairs", "A,D65,FL2"], "is not two illuminants"),
    (["--illuminants", "A,D65,FL2,D50"], "at most 3 lights"),
    (["--format", "exrr"], "did you mean 'exr'"),
    (["--format", "exr", "--pairs", "A,D65"], "drop --pairs"),
    (["--size", "12x"], "WxH"),
    (["--size", "5000x10", "--count", "1"], "exceeds the service's limits"),
    (["--split", "0.5,0.5"], "three fractions"),
    (["--gt", "physics"], "choose mixture (default), physical or formula"),
    (["--noise", "loud"], "noise"),
    (["--noise", "black_level:64.6"], "whole digital numbers"),
    (["--noise", "camera"], "--noise camera is /sample's"),  # not silently noise-free frames  # a DNG's BlackLevel, a TIFF's DN offset
    (["--format", "dng", "--size", "10x8"], "at least 22x22"),  # libraw refuses smaller DNGs
    (["--format", "exr", "--sensors", "XYZ", "--bayer", "BGGR"], "drop --sensors, --bayer"),
    (["--format", "exr", "--gt", "formula", "--noise", "none"], "drop --noise, --gt"),
    (["--format", "lsmi", "--exr-dtype", "float16"], "drop --exr-dtype"),
    (["--format", "lsmi", "--bayer", "BGGR"], "drop --bayer"),
    (["--format", "dng", "--exr-dtype", "float16"], "drop --exr-dtype"),
])
def test_cli_errors(store, tmp_path, capsys, args, says):
    line = assert_one_line_error(*run_cli(capsys, "export", store, str(tmp_path / "o"), *args))
    assert says in line
    assert not (tmp_path / "o").exists()  # refused before anything is written


def test_cli_missing_store_and_unwritable_out(store, tmp_path, capsys):
    line = assert_one_line_error(*run_cli(capsys, "export", str(tmp_path / "none"), str(tmp_path / "o")))
    assert "no illumix store" in line
    blocker = tmp_path / "file"
    blocker.write_text("")
    line = assert_one_line_error(*run_cli(capsys, "export", store, str(blocker / "o")))
    assert "cannot write into" in line


def test_cli_linear_dng(store, tmp_path, capsys):
    code, stdout, _ = run_cli(capsys, "export", store, str(tmp_path / "o"), "--format", "dng", "--bayer", "none",
                              "--count", "1", "--size", "32x24", "--json")
    assert code == 0 and json.loads(stdout)["bayer"] is None
    assert next((tmp_path / "o").rglob("*_12.dng")).is_file()


def test_cli_json_and_rerun_with_other_options(store, tmp_path, capsys):
    out = str(tmp_path / "o")
    code, stdout, _ = run_cli(capsys, "export", store, out, "--count", "2", "--json")
    assert code == 0 and json.loads(stdout)["counts"]["places"] == 2
    line = assert_one_line_error(*run_cli(capsys, "export", store, out, "--count", "3"))
    assert "other parameters (differing: count)" in line


def test_missing_extra_is_one_line(tmp_path, capsys, monkeypatch):
    """Without the export extra's packages: one line naming the install command, exit 2, nothing written."""
    import sys

    monkeypatch.setitem(sys.modules, "pidng", None)
    code, _, err = run_cli(capsys, "export", str(tmp_path / "nostore"), str(tmp_path / "out"), "--format", "dng")
    assert code == 2 and "pip install" in err and "pidng" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_resume_keeps_names_that_look_like_temporaries(tmp_path):
    """Store names may hold '.' (``demo.party``): a rerun deletes only the journal's own leftovers
    (regular files named ``.<name>.illumix-tmp<ext>``), never a folder or file of the export."""
    from illumix.dataset_export.journal import Journal, temp_path

    j = Journal(tmp_path, {"a": 1})
    real = j.write_bytes("Cam/demo.party-front/demo.party-front_1.tiff", b"x")
    j.write_bytes("Cam/demo.part-2.npy", b"y")
    leftover = temp_path(tmp_path / "Cam" / "demo.party-front" / "demo.party-front_12.tiff")
    leftover.write_bytes(b"half")
    (tmp_path / "Cam" / ".d.illumix-tmp.tiff").mkdir()  # not a regular file: left alone
    Journal(tmp_path, {"a": 1})
    assert real.read_bytes() == b"x" and (tmp_path / "Cam" / "demo.part-2.npy").is_file()
    assert not leftover.exists() and (tmp_path / "Cam" / ".d.illumix-tmp.tiff").is_dir()


def test_options_a_format_ignores_are_refused_by_the_library_too(store, tmp_path):
    """Not only the command line: ``export_dataset`` itself refuses what the format would drop."""
    from illumix.dataset_export.errors import ExportError
    from illumix.dataset_export.run import ExportOptions, export_dataset

    for kw in ({"format": "exr", "gt": "physical"}, {"format": "exr", "sensors": ["XYZ"]},
               {"format": "lsmi", "bayer": None}, {"format": "dng", "exr_dtype": "float16"}):
        with pytest.raises(ExportError, match="would change nothing"):
            export_dataset(ExportOptions(store=store, out=str(tmp_path / "o"), **kw))
        assert not (tmp_path / "o").exists()


def test_service_refusal_is_an_export_error(store):
    """Anything the service refuses (its ServiceError, an HTTP answer there) stops the export as one
    ExportError line (the CLI: exit 2), not a traceback."""
    from illumix.dataset_export.errors import ExportError
    from illumix.dataset_export.frames import Composer
    from illumix.dataset_export.plan import Place
    from illumix.retarget.sensor_model import NoiseModel
    from illumix.store import CubeStore

    composer = Composer(CubeStore.open(store, mode="r"), gt=None, size=(5000, 10), noise=None,
                        levels=NoiseModel(), bayer=None)
    with pytest.raises(ExportError, match="room_1/v0: output 5000x10 exceeds the limits"):
        composer.capture(Place("p", "room_1", "v0", ("window", "lamp"), ("A", "D65"), 1), "Nikon 5100 (NPL)")


def test_count_capped_at_distinct_places(store, tmp_path, capsys):
    """--count beyond the distinct view × lighting combinations writes each combination once (a repeat
    of a view takes a lighting it has not had) and says so in one warning line; no two places alike."""
    from illumix.dataset_export.plan import plan_places

    views = [("s1", "v0", ("a", "b")), ("s2", "v0", ("a", "b"))]
    lightings = [("A", "D65"), ("FL11", "D50")]
    places, _ = plan_places(views, lightings, count=30, seed=1)
    combos = [(p.scene, p.view, p.lighting) for p in places]
    assert len(combos) == len(set(combos)) == 4
    three, _ = plan_places(views, lightings, count=3, seed=1)
    assert len({(p.scene, p.lighting) for p in three}) == 3 and {p.scene for p in three} == {"s1", "s2"}
    code, stdout, err = run_cli(capsys, "export", store, str(tmp_path / "o"), "--count", "30", "--size", "16x12",
                                "--json")
    summary = json.loads(stdout)
    assert code == 0 and summary["counts"]["places"] == 5  # 5 views × the one default lighting
    assert "--count 30: the store has 5 distinct" in err and summary["warnings"]


@pytest.mark.parametrize("fmt", ["lsmi", "exr"])
def test_a_damaged_cube_is_one_line(tmp_path, capsys, fmt):
    """A corrupt chunk in the store: the store's own one-line error, exit 2 — not a traceback."""
    store = build_export_store(tmp_path / "store")
    (tmp_path / "store" / "scenes" / "room_1" / "v0" / "cubes" / "window" / "data" / "c" / "0" / "0" / "0").write_bytes(b"x")
    code, _, err = run_cli(capsys, "export", store, str(tmp_path / "o"), "--format", fmt)
    last = err.strip().splitlines()[-1]  # after the progress bar's line
    assert code == 2 and "Traceback" not in err and last.startswith("illumix: error: cube room_1/v0/window is damaged"), err
