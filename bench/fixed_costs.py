"""Fixed costs of rendering (issue 38): a new process, a new scene, a new light type — against a cube.

    python bench/fixed_costs.py

Each scenario runs in its own process with its own ``HOME`` (Dr.Jit keeps compiled kernels in
``~/.drjit``), so "cold" really starts from an empty kernel cache:

* ``demo_cold_cpu_s`` / ``demo_warm_cpu_s``: ``illumix render --demo --resolution 64x48 --spp 16``
  (6 cubes and 2 views, defaults) in a fresh process, with an empty and then with a filled cache
  (goal: cold ≤ 60 CPU-s).
* In one warm worker process (the cache filled by a first pass, as a long-lived worker has it), the
  CPU of each job in turn: a 240×180 cube of scene A, then a cube of scene B (other geometry, same
  light type: the fixed cost of a *new scene*), then scene B's point-light group (a *new light
  type* for that process), then B's first cube again (into another store: nothing new).
  ``new_scene_fixed_pct_of_240x180_cube``: (B's first cube − the same cube again) / the same cube
  again (goal ≤ 10 %).

CPU seconds (process time, all threads) so that other load on a shared machine does not count.
Human lines on stderr; one JSON object last on stdout.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

WORKER = r'''
import json, sys, time
sys.path.insert(0, sys.argv[1])
import yaml
from local_cluster import scene_file
from pathlib import Path
from illumix.renderer_jobs import jobs
from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scene.load import load_scenes

tmp = Path(sys.argv[2])
settings = RenderSettings(spp=16).model_dump(mode="json")
out = []

def scene(name, extra_shape, res):
    doc = yaml.safe_load(open(scene_file(tmp, 1)))
    doc["name"] = name
    for v in doc["views"]:
        v["resolution"] = list(res)
    if extra_shape:  # other geometry: a second ball and a box
        doc["shapes"] += [{"name": "ball2", "type": "sphere", "material": "grey", "center": [0.8, 0.3, 0.2],
                           "radius": 0.3},
                          {"name": "box", "type": "cube", "material": "cc",
                           "transform": {"scale": 0.25, "translate": [-0.8, 0.25, 0.3]}}]
    p = tmp / f"{name}.yaml"
    p.write_text(yaml.safe_dump(doc))
    return load_scenes(p)[0]

def run(s, store, group):
    p = jobs.plan([s], str(tmp / store), groups=[group])
    for job in p.jobs:
        t = time.process_time()
        jobs.run_job(jobs._scene_payload(s), job, str(tmp / store), settings, 2)
        out.append({"store": store, "job": job.label, "cpu_s": round(time.process_time() - t, 3)})

run(scene("warm", False, (240, 180)), "warmup", "lamp")  # a long-lived worker's kernels
run(scene("a", False, (240, 180)), "a", "lamp")
b = scene("b", True, (240, 180))
run(b, "b", "lamp")    # scene B's first cube in this process: new scene (its kernels, its data)
run(b, "b", "bulb")    # its point light: a light type this process has not rendered yet
run(b, "b2", "lamp")   # scene B's same cube again: what the cube costs without anything new
print(json.dumps(out))
'''


def say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def cpu_of(cmd: list[str], env: dict) -> tuple[float, float, str]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"{' '.join(cmd[:4])} failed: {r.stderr.strip()[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, time.perf_counter() - t0, r.stdout


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        env = {**os.environ, "HOME": str(tmp / "home")}
        (tmp / "home").mkdir()
        demo = ["illumix", "render", "--demo", "--resolution", "64x48", "--spp", "16", "--json"]
        cold, cold_wall, _ = cpu_of([*demo, "--store", str(tmp / "d1")], env)
        say(f"64x48 demo, fresh process, empty kernel cache: {cold:.1f} CPU-s ({cold_wall:.0f} s)")
        warm, warm_wall, _ = cpu_of([*demo, "--store", str(tmp / "d2")], env)
        say(f"64x48 demo, fresh process, kernel cache filled: {warm:.1f} CPU-s ({warm_wall:.0f} s)")
        _, _, out = cpu_of([sys.executable, "-c", WORKER, str(ROOT / "scripts"), str(tmp)], env)
        rows = json.loads(out.strip().splitlines()[-1])
        for r in rows:
            say(f"  {r['store']}: {r['job']} 240x180: {r['cpu_s']:.2f} CPU-s")
        a = next(r["cpu_s"] for r in rows if r["store"] == "a" and r["job"].endswith("/lamp"))
        b_same = next(r["cpu_s"] for r in rows if r["store"] == "b" and r["job"].endswith("/lamp"))
        b_point = next(r["cpu_s"] for r in rows if r["store"] == "b" and r["job"].endswith("/bulb"))
        b_again = next(r["cpu_s"] for r in rows if r["store"] == "b2" and r["job"].endswith("/lamp"))
        result = {"demo_cold_cpu_s": round(cold, 1), "demo_warm_cpu_s": round(warm, 1),
                  "kernel_build_cpu_s": round(cold - warm, 1), "demo_goal_met": cold <= 60.0,
                  "cube_240x180_cpu_s": a, "new_scene_cube_cpu_s": b_same, "new_light_type_cube_cpu_s": b_point,
                  "same_cube_again_cpu_s": b_again,
                  "new_scene_fixed_cpu_s": round(b_same - b_again, 2),
                  "new_scene_fixed_pct_of_240x180_cube": round(100 * max(b_same - b_again, 0.0) / b_again, 1),
                  "jobs": rows}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
