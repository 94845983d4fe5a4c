"""The held-out fidelity corpus of ``bench/fidelity.py``: scenes the renderer's and the denoiser's
defaults were never chosen on, rendered through the job runner exactly as ``illumix render`` does.

Per scene three stores under the cache: two production renders (the defaults: 64 spp, the targeted
extra paths, the denoised copies; seeds 101 and 102) and a reference (≥ 16× the production's
mean paths per pixel, no extra paths, no denoising; seed 103). The reference is kept between runs
(it does not depend on the denoiser); the production stores are rendered again unless ``reuse``.

Corpus entries (``ENTRIES``): the adversarial scene files in ``bench/fidelity_scenes/``, the
example scene at 640×480, procedural rooms from seeds used nowhere else, and an OBJ import built
here with trimesh (a torus, a cone and a box under an emissive panel: ``Ke`` in the MTL).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PROD_SEEDS = (101, 102)
REF_SEED = 103
REF_FACTOR = 16  # the reference's paths per pixel over the production's mean


@dataclass(frozen=True)
class Entry:
    """One corpus scene: ``kind`` ``"file"`` (``source`` a scene file), ``"room"`` (``source`` a
    scenegen seed), ``"demo"`` (the demo room of seed ``source``) or ``"obj"`` (built here); its
    ``view`` at ``resolution`` (W, H)."""

    name: str
    kind: str
    source: str
    view: str
    resolution: tuple[int, int]
    what: str


_S = "bench/fidelity_scenes/"
ENTRIES: tuple[Entry, ...] = (
    Entry("lamps-in-frame", "file", _S + "lamps_in_frame.yaml", "low", (64, 48), "small and large emitters in frame"),
    Entry("spot-cone", "file", _S + "spot_cone.yaml", "down", (96, 72), "a spot cone's rim on floor and wall"),
    Entry("hard-shadows", "file", _S + "hard_shadows.yaml", "table", (128, 96), "point-light and sun hard shadows, thin legs"),
    Entry("sun-window", "file", _S + "sun_window.yaml", "room", (160, 120), "a sun patch through a window, sky portal in frame"),
    Entry("glass-mirror", "file", _S + "glass_mirror.yaml", "front", (120, 90), "glass ball, mirror, glossy floor highlight"),
    Entry("textures", "file", _S + "textures.yaml", "wide", (200, 150), "fine spectral textures, shaded lamp"),
    Entry("thin-grazing", "file", _S + "thin_grazing.yaml", "low", (80, 60), "slats and rods in grazing sun, sky in frame"),
    Entry("two-lamps-640", "file", "renderer_jobs/examples/two_lamps.yaml", "wide", (640, 480),
          "the example scene at 640x480: spot, panel, glass, chrome"),
    Entry("room-4242", "room", "4242", "view0", (160, 120), "procedural room, held-out seed"),
    Entry("room-5151", "room", "5151", "view0", (120, 90), "procedural room, held-out seed"),
    Entry("room-6363", "room", "6363", "view0", (240, 180), "procedural room, held-out seed"),
    Entry("obj-import", "obj", "", "default", (100, 75), "an OBJ + MTL import (trimesh meshes, Ke panel)"),
)
#: Where the new defaults (the direct-light test's floor and tolerance, the shading's floor) were
#: chosen: the demo room the earlier ones were tuned on. Reported apart (``--tuning``).
TUNING = (Entry("demo-front", "demo", "0", "front", (160, 120), "the demo room, view front (tuning)"),
          Entry("demo-corner", "demo", "0", "corner", (160, 120), "the demo room, view corner (tuning)"))
#: The suite's corpus (tests/test_fidelity.py): the two failures the issue measured, made small.
QUICK = (Entry("lamps-in-frame", "file", _S + "lamps_in_frame.yaml", "low", (64, 48), "emitters in frame"),
         Entry("spot-cone", "file", _S + "spot_cone.yaml", "down", (64, 48), "a spot cone's rim"))


def entry_named(name: str, entries=ENTRIES) -> Entry:
    for e in entries:
        if e.name == name:
            return e
    raise SystemExit(f"fidelity: no corpus scene {name!r}; choose from {', '.join(e.name for e in entries)}")


def _obj_scene(work: Path) -> Path:
    """Write the OBJ + MTL of the import case into ``work`` (trimesh meshes); returns the .obj."""
    import trimesh

    work.mkdir(parents=True, exist_ok=True)
    parts = {"floor": trimesh.creation.box((4.0, 0.02, 4.0)).apply_translation((0, -0.01, 0)),
             "back": trimesh.creation.box((4.0, 2.5, 0.02)).apply_translation((0, 1.25, -1.5)),
             "torus": trimesh.creation.torus(0.35, 0.12).apply_transform(
                 trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0))).apply_translation((-0.5, 0.12, -0.3)),
             "cone": trimesh.creation.cone(0.25, 0.7).apply_transform(
                 trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0))).apply_translation((0.6, 0.0, -0.6)),
             "box": trimesh.creation.box((0.4, 0.4, 0.4)).apply_translation((0.1, 0.2, -1.0)),
             "panel": trimesh.creation.box((0.8, 0.02, 0.5)).apply_translation((0.0, 2.3, -0.4))}
    colours = {"floor": "0.45 0.40 0.35", "back": "0.7 0.7 0.7", "torus": "0.7 0.15 0.1",
               "cone": "0.1 0.3 0.6", "box": "0.2 0.55 0.2", "panel": "0.8 0.8 0.8"}
    lines, mtl, base = ["mtllib scene.mtl"], [], 1
    for name, mesh in parts.items():
        lines.append(f"o {name}")
        lines.append(f"usemtl m_{name}")
        lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in mesh.vertices]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in mesh.faces]
        base += len(mesh.vertices)
        mtl += [f"newmtl m_{name}", f"Kd {colours[name]}"] + (["Ke 6 5.5 4.5"] if name == "panel" else []) + [""]
    (work / "scene.mtl").write_text("\n".join(mtl))
    path = work / "scene.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def load(entry: Entry, cache: Path):
    """The entry's :class:`scene.model.Scene`, its one view at the entry's resolution."""
    from illumix.renderer_jobs.jobs import apply_resolution
    from illumix.scene.load import load_scenes, scene_from_dict

    if entry.kind == "file":
        scene = load_scenes(ROOT / entry.source)[0]
        scene = scene.model_copy(update={"views": [v for v in scene.views if v.name == entry.view]})
    elif entry.kind == "demo":
        from illumix.scene.demo import demo_room_dict

        doc = demo_room_dict(int(entry.source), entry.resolution)
        doc["views"] = [v for v in doc["views"] if v["name"] == entry.view]
        scene = scene_from_dict(doc, source=entry.name)
    elif entry.kind == "room":
        import json

        # generated once and kept with the stores: the corpus stays the scenes its stores were
        # rendered from while the generator changes (the document records its generator version)
        frozen = cache / entry.name / "room.json"
        if frozen.is_file():
            doc = json.loads(frozen.read_text())
        else:
            from illumix.scenegen.generate import GeneratorConfig, generate_doc

            doc = generate_doc(int(entry.source), GeneratorConfig(probe=False))
            doc["views"] = [v for v in doc["views"] if v["name"] == entry.view][:1] or doc["views"][:1]
            doc["views"][0]["name"] = entry.view
            frozen.parent.mkdir(parents=True, exist_ok=True)
            frozen.write_text(json.dumps(doc))
        scene = scene_from_dict(doc, source=entry.name)
    else:
        from illumix.scene_import import import_scene

        work = cache / entry.name / "import"
        doc, _ = import_scene(_obj_scene(work / "src"), work / "doc")
        doc["views"] = doc["views"][:1]
        doc["views"][0]["name"] = entry.view
        scene = scene_from_dict(doc, source=entry.name, base=work / "doc")
    return apply_resolution(scene, entry.resolution)


def view_of(scene) -> str:
    """The corpus scene's one view."""
    return scene.views[0].name


def _complete(store: Path, scene) -> bool:
    from illumix.store import CubeStore

    if not CubeStore.exists(str(store)):
        return False
    st = CubeStore.open(str(store), mode="r")
    view = view_of(scene)
    return all(st.is_complete(scene.name, view, g) for g in scene.group_names)


def render(scene, store: Path, settings, log: Callable[[str], None], groups=None, keep_guides: Path | None = None) -> float:
    """Render ``scene`` (its groups, or ``groups``) into ``store`` with the job runner (in this
    process); returns the CPU seconds spent. ``keep_guides``: a folder where each denoising's
    guides are saved, ``<view>-<group>-<kind>.npz`` (the operator the store's copies were made with)."""
    import time

    from illumix.renderer_jobs import jobs

    from illumix.renderer_jobs.execute import execute

    t = time.process_time()
    with _keeping_guides(keep_guides):
        execute(jobs.plan([scene], str(store), groups=groups), str(store), settings)
    cpu = time.process_time() - t
    log(f"  {store.name}: {cpu:.1f} s CPU")
    return cpu


class _keeping_guides:
    """Within it, every denoising the job runner does saves its guides (``retarget.denoise.denoise``
    wrapped; the job runner imports it at call time and runs one job at a time in this process)."""

    def __init__(self, folder: Path | None) -> None:
        self.folder = folder

    def __enter__(self):
        if self.folder is None:
            return self
        import illumix.retarget.denoise as rd
        from illumix.renderer_jobs import jobs

        self.rd, self.jobs = rd, jobs
        self.real, self.real_job = rd.denoise, jobs._denoise
        self.folder.mkdir(parents=True, exist_ok=True)
        current = {}

        def job_denoise(st, scene, job, *a, **k):
            current["group"], current["view"] = job.group, job.view
            return self.real_job(st, scene, job, *a, **k)

        def keep(cube, guides, method=rd.DEFAULT_METHOD, kind="transport", **params):
            arrays = {f: getattr(guides, f) for f in guides.__dataclass_fields__ if getattr(guides, f) is not None}
            np.savez(self.folder / f"{current['view']}-{current['group']}-{kind}.npz", **arrays)
            return self.real(cube, guides, method, kind, **params)

        rd.denoise, jobs._denoise = keep, job_denoise
        return self

    def __exit__(self, *exc) -> None:
        if self.folder is not None:
            self.rd.denoise, self.jobs._denoise = self.real, self.real_job


def operator_on_reference(ref: Path, guides: Path, out: Path, scene, groups: list[str]) -> Path:
    """A copy of the reference store whose denoised copies are the production's operator (its saved
    guides, the cube noise included) applied to the reference's own cubes: served by default it
    gives the default's expectation, nearly noise-free — the bias alone."""
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(ref, out)
    return denoise_again(out, guides, scene, groups)


def denoise_again(store: Path, guides: Path, scene, groups: list[str]) -> Path:
    """``store``'s denoised copies made again, in place, by today's default denoiser from the saved
    ``guides`` (``--redenoise``: a change to the denoiser measured on the same renders)."""
    from illumix.retarget.denoise import DEFAULT_METHOD, Guides, denoise, describe
    from illumix.store import CubeStore
    from illumix.store.schema import DenoisedInfo

    st, view = CubeStore.open(str(store), mode="a"), view_of(scene)
    for g in groups:  # the lit ones: each was denoised, so its guides must be there
        if not (guides / f"{view}-{g}-transport.npz").exists():
            raise SystemExit(f"fidelity: no saved guides of {view}/{g} in {guides}; render the production stores "
                             "again (without --reuse)")
        cubes = {k: st.read_cube(scene.name, view, g, kind=k) for k in ("transport", "illumination")}
        den = {}
        for kind, cube in cubes.items():
            with np.load(guides / f"{view}-{g}-{kind}.npz") as z:
                gd = Guides(**{k: z[k] for k in z.files})
            den[kind] = denoise(cube, gd, DEFAULT_METHOD, kind)
        meta = st.cube_meta(scene.name, view, g)
        meta.denoised = DenoisedInfo(**describe(DEFAULT_METHOD))
        st.write_cube(scene.name, view, g, cubes["transport"], meta, overwrite=True, illumination=cubes["illumination"],
                      denoised=den)
    return store


def production_paths(store: Path, scene, group: str) -> float:
    """Mean paths per pixel of a production cube (its spp plus the targeted extra paths)."""
    from illumix.store import CubeStore

    meta = CubeStore.open(str(store), mode="r").cube_meta(scene.name, view_of(scene), group)
    tp = (meta.render_stats or {}).get("targeted_paths") or {}
    extra = tp.get("pixel_fraction", 0.0) * (tp.get("paths_per_pixel", meta.spp) - meta.spp)
    return float(meta.spp + extra)


def build(entry: Entry, cache: Path, log: Callable[[str], None], reuse: bool = False, redenoise: bool = False) -> dict:
    """Render (or reuse) the three stores of ``entry``; returns ``{"scene", "prod": [paths],
    "ref": path, "ref_spp": {group: spp}, "prod_paths": {group: paths}, "cpu_s"}``."""
    from denoise_lib import exact_spp_bracket  # the spp the sampler renders exactly (no rounding up)
    from illumix.renderer_jobs.render_settings import RenderSettings

    scene = load(entry, cache)
    res = entry.resolution
    base = cache / entry.name
    _forget_if_changed(base, scene)
    prods = [base / f"prod-{s}" for s in PROD_SEEDS]
    cpu = 0.0
    for seed, p in zip(PROD_SEEDS, prods):
        if not (reuse and _complete(p, scene)):
            shutil.rmtree(p, ignore_errors=True)
            shutil.rmtree(base / f"guides-{seed}", ignore_errors=True)
            cpu += render(scene, p, RenderSettings(seed=seed, resolution=res), log, keep_guides=base / f"guides-{seed}")
        elif redenoise:
            denoise_again(p, base / f"guides-{seed}", scene, [g for g in scene.group_names if _lit(p, scene, g)])
    paths = {g: max(production_paths(p, scene, g) for p in prods) for g in scene.group_names
             if _lit(prods[0], scene, g)}
    ref = base / "ref"
    # one store, each group at its own spp (16x the production's paths of that group)
    ref_spp = {g: exact_spp_bracket(max(64.0, REF_FACTOR * n))[1] for g, n in paths.items()}
    have = _stored_spp(ref, scene)
    if any(have.get(g, spp) < spp for g, spp in ref_spp.items()):
        shutil.rmtree(ref)  # made for fewer production paths: a store holds one cube per group
        have = {}
    ref_spp = {g: max(spp, have.get(g, 0)) for g, spp in ref_spp.items()}  # a reference with more paths serves too
    for g, spp in ref_spp.items():
        if g not in have:
            cpu += render(scene, ref, RenderSettings(seed=REF_SEED, resolution=res, spp=spp, denoise=None,
                                                     boost_factor=1), log, groups=[g])
    ref_op = operator_on_reference(ref, base / f"guides-{PROD_SEEDS[0]}", base / "ref-op", scene, list(paths))
    return {"scene": scene, "prod": prods, "ref": ref, "ref_op": ref_op, "ref_spp": ref_spp, "prod_paths": paths,
            "cpu_s": cpu}


def _forget_if_changed(base: Path, scene) -> None:
    """Remove ``base``'s stores when the scene they were rendered from is not ``scene`` any more (a
    generated room after a change to the generator, an import after a change to the importer):
    reused, they would measure another scene than the one named."""
    import hashlib

    digest = hashlib.sha256(scene.model_dump_json(exclude_defaults=True).encode()).hexdigest()
    stamp = base / "scene.sha256"
    if stamp.is_file() and stamp.read_text().strip() == digest:
        return
    for name in [*(f"{k}-{s}" for s in PROD_SEEDS for k in ("prod", "guides")), "ref", "ref-op"]:
        shutil.rmtree(base / name, ignore_errors=True)
    base.mkdir(parents=True, exist_ok=True)
    stamp.write_text(digest + "\n")


def _lit(store: Path, scene, group: str) -> bool:
    from illumix.store import CubeStore

    st = CubeStore.open(str(store), mode="r")
    return not st.cube_meta(scene.name, view_of(scene), group).render_stats.get("skipped")


def _stored_spp(store: Path, scene) -> dict[str, int]:
    """``{group: spp}`` of the complete cubes in ``store``."""
    from illumix.store import CubeStore

    if not CubeStore.exists(str(store)):
        return {}
    st, view = CubeStore.open(str(store), mode="r"), view_of(scene)
    return {g: st.cube_meta(scene.name, view, g).spp for g in scene.group_names if st.is_complete(scene.name, view, g)}
