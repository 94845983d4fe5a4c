"""Fixed costs of rendering (issue 38): a new process, a new scene, a new light type — against a cube.

    python bench/fixed_costs.py

Each scenario runs in its own process with its own ``HOME`` (Dr.Jit keeps compiled kernels in
``~/.drjit``), so "cold" really starts from an empty kernel cache:

* ``demo_cold_cpu_s`` / ``demo_warm_cpu_s``: ``illumix render --demo --resolution 64x48 --spp 16``
  (6 cubes and 2 views, defaults) in a fresh process, with an empty and then with a filled cache
  (goal: cold ≤ 60 CPU-s).
* In one warm worker process (the cache filled by a first pass, as a long-lived worker has it), the
  CPU of each job in turn: a 240×180 cube of scene A, then for three new scenes B1–B3 (other
  geometry each, same light type) their first cube — the fixed cost of a *new scene* — and the same
  cube again (into another store: nothing new); and B1's point-light group (a *new light type* for
  that process). ``new_scene_fixed_pct_of_240x180_cube``: the mean of (first − again) over B1–B3
  / the mean cube again (goal ≤ 10 %); ``new_scene_fixed_spread_pct`` the spread of the three
  (a shared machine's noise; ±0.3–0.5 CPU-s a cube); ``new_scene_kernel_build_s`` the same fixed cost
  free of that noise: the build time of the kernels its first cube and view job had to build (Dr.Jit's
  kernel history), ``new_scene_kernel_build_pct_of_240x180_cube`` its mean against the cube; ``new_scene_fixed_pct_of_default_cube`` the same fixed cost against
  the cube at the default settings (64 spp; the scenes above use 16, as the issue's commands do).

All of it twice: with Dr.Jit's instance registry padded (the default, :mod:`renderer_jobs.mitsuba.
instance_padding`) and without (``padding_off``, ``ILLUMIX_KERNEL_PADDING=off``: the baseline of the
same run); ``padding_cost_*_pct`` is what padding costs where it cannot help (the same cube again,
the warm demo).

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

import drjit as dr
dr.set_flag(dr.JitFlag.KernelHistory, True)  # which kernels each job had to build (not in memory)
tmp = Path(sys.argv[2])
settings = RenderSettings(spp=16).model_dump(mode="json")
out = []

def scene(name, extra_shape, res):
    doc = yaml.safe_load(open(scene_file(tmp, 1)))
    doc["name"] = name
    for v in doc["views"]:
        v["resolution"] = list(res)
    for k in range(extra_shape):  # other geometry: more balls and boxes, each scene its own
        doc["shapes"] += [{"name": f"ball{k + 2}", "type": "sphere", "material": "grey",
                           "center": [0.8 - 0.3 * k, 0.3, 0.2 + 0.2 * k], "radius": 0.3 - 0.05 * k},
                          {"name": f"box{k}", "type": "cube", "material": "cc",
                           "transform": {"scale": 0.25, "translate": [-0.8 + 0.2 * k, 0.25, 0.3 - 0.3 * k]}}]
    p = tmp / f"{name}.yaml"
    p.write_text(yaml.safe_dump(doc))
    return load_scenes(p)[0]

def run(s, store, group, config=settings):
    p = jobs.plan([s], str(tmp / store), groups=[group])
    for job in p.jobs:
        dr.kernel_history()  # cleared
        t = time.process_time()
        jobs.run_job(jobs._scene_payload(s), job, str(tmp / store), config, 2)
        cpu = round(time.process_time() - t, 3)
        built = [e for e in dr.kernel_history() if str(e.get("type")).endswith("JIT")
                 and (not e.get("cache_hit") or e.get("cache_disk"))]
        out.append({"store": store, "job": job.label, "cpu_s": cpu, "kernels_built": len(built),
                    "build_s": round(sum(e.get("backend_time", 0.0) + e.get("codegen_time", 0.0) for e in built) / 1e3, 3)})

run(scene("warm", 0, (240, 180)), "warmup", "lamp")  # a long-lived worker's kernels
run(scene("a", 0, (240, 180)), "a", "lamp")
for k in (1, 2, 3):  # new scenes, each rendered twice: the first time pays what a new scene costs
    b = scene(f"b{k}", k, (240, 180))
    run(b, f"b{k}", "lamp")        # its first cube in this process (its kernels, its data)
    if k == 1:
        run(b, f"b{k}", "bulb")    # its point light: a light type this process has not rendered yet
    run(b, f"b{k}-again", "lamp")  # the same cube again: what the cube costs without anything new
run(b, "b3-default", "lamp", RenderSettings().model_dump(mode="json"))  # the cube at the default spp
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


def measure(tmp: Path, padding: str) -> dict:
    """Every figure above with Dr.Jit's instance registry padded (``on``, the default) or not
    (``off``: ``ILLUMIX_KERNEL_PADDING=off``, the baseline), each in its own ``HOME``."""
    home = tmp / f"home-{padding}"
    home.mkdir()
    env = {**os.environ, "HOME": str(home), "ILLUMIX_KERNEL_PADDING": padding}
    demo = ["illumix", "render", "--demo", "--resolution", "64x48", "--spp", "16", "--json"]
    cold, cold_wall, _ = cpu_of([*demo, "--store", str(tmp / f"d1-{padding}")], env)
    say(f"[padding {padding}] 64x48 demo, fresh process, empty kernel cache: {cold:.1f} CPU-s ({cold_wall:.0f} s)")
    warm, warm_wall, _ = cpu_of([*demo, "--store", str(tmp / f"d2-{padding}")], env)
    say(f"[padding {padding}] 64x48 demo, fresh process, kernel cache filled: {warm:.1f} CPU-s ({warm_wall:.0f} s)")
    work = tmp / f"w-{padding}"
    work.mkdir()
    _, _, out = cpu_of([sys.executable, "-c", WORKER, str(ROOT / "scripts"), str(work)], env)
    rows = json.loads(out.strip().splitlines()[-1])
    for r in rows:
        say(f"  [padding {padding}] {r['store']}: {r['job']} 240x180: {r['cpu_s']:.2f} CPU-s, "
            f"{r['kernels_built']} kernels built ({r['build_s']:.2f} s)")
    cube = lambda store, group="lamp": next(r["cpu_s"] for r in rows
                                            if r["store"] == store and r["job"].endswith("/" + group))
    firsts = [cube(f"b{k}") for k in (1, 2, 3)]
    agains = [cube(f"b{k}-again") for k in (1, 2, 3)]
    fixed = [f - a for f, a in zip(firsts, agains)]
    # the same fixed cost without the timing noise of two cubes: the kernels the first cube built
    # (view job and cube; LLVM builds are single-threaded, so seconds = CPU seconds)
    builds = [sum(r["build_s"] for r in rows if r["store"] == f"b{k}" and not r["job"].endswith("/bulb"))
              for k in (1, 2, 3)]
    mean_again = sum(agains) / len(agains)
    mean_fixed = sum(fixed) / len(fixed)
    return {"demo_cold_cpu_s": round(cold, 1), "demo_warm_cpu_s": round(warm, 1),
            "kernel_build_cpu_s": round(cold - warm, 1), "demo_goal_met": cold <= 60.0,
            "cube_240x180_cpu_s": cube("a"), "new_scene_cube_cpu_s": firsts,
            "new_light_type_cube_cpu_s": cube("b1", "bulb"), "same_cube_again_cpu_s": agains,
            "new_scene_fixed_cpu_s": [round(x, 2) for x in fixed],
            "new_scene_kernel_build_s": [round(x, 2) for x in builds],
            "new_scene_kernel_build_pct_of_240x180_cube": round(100 * sum(builds) / len(builds) / mean_again, 1),
            "new_scene_fixed_pct_of_240x180_cube": round(100 * max(mean_fixed, 0.0) / mean_again, 1),
            "new_scene_fixed_spread_pct": round(100 * (max(fixed) - min(fixed)) / mean_again, 1),
            "new_scene_goal_met": mean_fixed <= 0.10 * mean_again,
            "cube_240x180_default_spp_cpu_s": cube("b3-default"),
            "new_scene_fixed_pct_of_default_cube": round(100 * max(mean_fixed, 0.0) / cube("b3-default"), 1),
            "jobs": rows}


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        result = measure(tmp, "on")
        off = measure(tmp, "off")
    result["padding_off"] = {k: v for k, v in off.items() if k != "jobs"}
    # what the padding costs where it cannot help: the same cubes again, and a warm demo
    result["padding_cost_same_cube_pct"] = round(
        100 * (sum(result["same_cube_again_cpu_s"]) / sum(off["same_cube_again_cpu_s"]) - 1), 1)
    result["padding_cost_demo_warm_pct"] = round(100 * (result["demo_warm_cpu_s"] / off["demo_warm_cpu_s"] - 1), 1)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
