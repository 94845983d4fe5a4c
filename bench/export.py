"""Benchmark: ``illumix export`` throughput per format (issue 20: images/s).

A small store: ``--scenes`` scenes × one 240×320×63 view (the demo room's size) × two light groups,
each a :func:`store.synth.synthetic_cube` (a room-like path-traced-looking cube; formula ground
truth, no illumination cubes). Each format is exported once into a fresh folder, timed end to end
(composition, encoding, atomic writes, checksums, card, manifest); the baseline measured in the same
run is composition alone (``build_sample`` of the same frames, no writing), so ``write_overhead`` is
what the export adds on top of the service's own work. A second, resumed run over the complete
export measures the skip path (checksum verification only).

Usage: ``python bench/export.py [--scenes 4]``. Progress goes to stderr; the JSON
result is the last line on stdout.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def build_store(path: Path, scenes: int, h: int = 240, w: int = 320) -> str:
    import numpy as np

    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.store import CubeMeta, CubeStore, ViewMeta
    from illumix.store.synth import synthetic_cube

    st = CubeStore.open(str(path), mode="a")
    common = dict(grid=DEFAULT_GRID.to_dict(), renderer={"name": "synthetic", "version": "1"}, spp=0, seed=0,
                  scene_hash="synthetic", emission=[1.0] * DEFAULT_GRID.n_bands, emission_name="flat")
    for s in range(scenes):
        st.write_view(f"room{s}", "front", ViewMeta(width=w, height=h, fov=60.0),
                      {"mask": np.ones((h, w), bool), "emitter": np.zeros((h, w), bool)})
        for g, name in enumerate(("window", "lamp")):
            cube = synthetic_cube(h, w, seed=100 * s + g, emitter=20.0)
            st.write_cube(f"room{s}", "front", name, cube, CubeMeta(**common))
    return str(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", type=int, default=4)
    args = ap.parse_args()
    from illumix.dataset_export.frames import Composer
    from illumix.dataset_export.plan import parse_lightings, plan_places
    from illumix.dataset_export.run import ExportOptions, _open_store, _views, export_dataset
    from illumix.retarget.sensor_model import NoiseModel

    tmp = Path(tempfile.mkdtemp(prefix="illumix-bench-export-"))
    t0 = time.perf_counter()
    store = build_store(tmp / "store", args.scenes)
    print(f"store: {args.scenes} scenes in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    # baseline: composing the frames an lsmi export writes, without writing anything
    st = _open_store(store)
    places, _ = plan_places(_views(st), parse_lightings(None, None), count=None, seed=0)
    comp = Composer(st, gt=None, size=None, noise=None, levels=NoiseModel(), bayer=None)
    t0 = time.perf_counter()
    frames = sum(len(comp.capture(p, "Nikon 5100 (NPL)").frames) for p in places)
    compose_s = time.perf_counter() - t0
    result = {"bench": "export", "platform": platform.platform(), "python": platform.python_version(),
              "store": {"scenes": args.scenes, "size": "320x240", "bands": 63, "groups": 2},
              "baseline_compose_only": {"frames": frames, "seconds": round(compose_s, 3),
                                        "frames_per_s": round(frames / compose_s, 2)}, "formats": {}}
    for fmt in ("lsmi", "dng", "exr"):
        out = tmp / fmt
        t0 = time.perf_counter()
        s = export_dataset(ExportOptions(store=store, out=str(out), format=fmt))
        dt = time.perf_counter() - t0
        t1 = time.perf_counter()
        export_dataset(ExportOptions(store=store, out=str(out), format=fmt))
        resume = time.perf_counter() - t1
        n = s["counts"].get("raw frames", s["counts"].get("spectral EXR files"))
        mb = sum(p.stat().st_size for p in out.rglob("*") if p.is_file()) / 2**20
        row = {"images": n, "seconds": round(dt, 3), "images_per_s": round(n / dt, 2), "mb_written": round(mb, 1),
               "resume_skip_s": round(resume, 3)}
        if fmt != "exr":
            row["write_overhead"] = round(dt / compose_s, 2)
        result["formats"][fmt] = row
        print(f"{fmt}: {row}", file=sys.stderr)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
