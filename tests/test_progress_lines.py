"""Progress everywhere (issue 38): plain progress lines with rate, ETA and a heartbeat when stderr
is not a terminal (``illumix render``/``dataset`` through :func:`illumix.render_run.run_jobs`, the
local and Ray executors), the rich bar on a terminal, and ``--dry-run`` estimates from the cost
model (:mod:`renderer_jobs.cost_model`). Jobs are faked (no Mitsuba) except in one tiny render."""

from __future__ import annotations

import io
import json
import re
import sys
import time
import types

import pytest
from cli_testutil import run_cli
from illumix.renderer_jobs import cost_model, jobs
from illumix.renderer_jobs.render_settings import RenderSettings
from rich.console import Console
from test_render_cli import needs_mitsuba, tiny_scene_file

from illumix.progress import ProgressLines, duration


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def lines_for(order, **kw):
    out: list[str] = []
    clock = Clock()
    return ProgressLines(out.append, order, clock=clock, **kw), out, clock


# -- ProgressLines --------------------------------------------------------------------------------
def test_duration_reads_well():
    assert [duration(s) for s in (0.84, 42.4, 185, 600, 7800)] == ["0.8 s", "42 s", "3 min 5 s", "10 min", "2 h 10 min"]


def test_a_line_per_job_with_rate_and_weighted_eta():
    order = [("s/a/[view+aovs]", 0), ("s/a/lamp", 1), ("s/a/bulb", 1)]
    pl, out, clock = lines_for(order, weights={"s/a/[view+aovs]": 1, "s/a/lamp": 3, "s/a/bulb": 6})
    clock.t += 2
    pl.job_done("s/a/[view+aovs]", 2.0)
    assert out[-1] == "[1/3] finished s/a/[view+aovs] in 2.0 s; 1/3 done, 2.0 s per job, ETA 18 s"
    clock.t += 6
    pl.job_done("s/a/lamp", 6.0, "lights nothing in its view: recorded as empty")
    assert out[-1].startswith("[2/3] finished s/a/lamp in 6.0 s (lights nothing in its view: recorded as empty); "
                              "2/3 done, 4.0 s per job, ETA 12 s")  # 8 s for weight 4: weight 6 left
    clock.t += 12
    pl.job_failed("s/a/bulb", "RuntimeError: boom")
    assert out[-1] == "[3/3] failed s/a/bulb: RuntimeError: boom; 3/3 done (1 failed), 6.7 s per job"


def test_heartbeat_names_the_running_job_after_the_interval():
    order = [("m/a/[view+aovs]", 0), ("m/a/lamp", 1), ("m/a/bulb", 1)]
    pl, out, clock = lines_for(order, interval=10)
    clock.t += 1
    pl.job_done("m/a/[view+aovs]", 1.0)
    clock.t += 5
    assert not pl.heartbeat() and len(out) == 1  # a line 5 s ago: no heartbeat yet
    clock.t += 40
    assert pl.heartbeat()
    assert out[-1] == "still rendering m/a/lamp: 45 s, 1/3 done, 1.0 s per job, ETA 1 min 32 s"
    clock.t += 3
    assert not pl.heartbeat()  # every `interval` s, not every call
    pl.pass_done("pass 2/21 diffuse")
    clock.t += 10
    assert pl.heartbeat() and out[-1].startswith("still rendering m/a/lamp (pass 2/21 diffuse): 58 s, ")


def test_heartbeat_before_any_job_and_with_parallel_workers():
    order = [("r/v/[view+aovs]", 0)] + [(f"r/v/g{i}", 1) for i in range(4)]
    pl, out, clock = lines_for(order, parallel=2)
    assert [lbl for lbl, _ in pl.running()] == ["r/v/[view+aovs]"]  # cubes wait for their view
    clock.t += 12
    pl.heartbeat()
    assert out[-1] == "still rendering r/v/[view+aovs]: 12 s, 0/5 done, ETA after the first job"
    pl.job_done("r/v/[view+aovs]", 12)
    clock.t += 20
    pl.job_done("r/v/g1", 20)  # out of order: g0 runs on, g2 starts
    clock.t += 30
    pl.heartbeat()
    assert out[-1].startswith("still rendering r/v/g0 (50 s), r/v/g2 (30 s): 2/5 done, ")


def test_heartbeat_without_known_parallelism_ray():
    pl, out, clock = lines_for([("x/v/g", 1), ("x/v/h", 1)], parallel=None)
    clock.t += 11
    pl.heartbeat()
    assert out[-1] == "still rendering: 11 s so far, 0/2 done, ETA after the first job"


def test_heartbeat_thread_writes_and_stops():
    out: list[str] = []
    with ProgressLines(out.append, [("q/v/g", 1)], interval=0.05):
        time.sleep(0.4)
    n = len(out)
    time.sleep(0.15)
    assert n >= 2 and len(out) == n and all(line.startswith("still rendering q/v/g: ") for line in out)


# -- the cost model -------------------------------------------------------------------------------
def _plan(tmp_path, resolution=None, groups=None):
    from illumix.scene_files import load_scene_file

    scenes = [jobs.apply_resolution(s, resolution) for s in load_scene_file(tiny_scene_file(tmp_path))]
    return jobs.plan(scenes, None, groups=groups)


def test_estimate_scales_with_pixels_spp_groups_boost_and_workers(tmp_path):
    s16, s64 = RenderSettings(spp=16, boost_factor=1), RenderSettings(spp=64, boost_factor=1)
    small, big = _plan(tmp_path, (80, 60)), _plan(tmp_path, (160, 120))
    per_path = cost_model.PER_MPATH_S / 1e6
    e16, e64 = cost_model.estimate(small, s16), cost_model.estimate(small, s64)
    assert e16.paths == 4 * 80 * 60 * 16 and e64.cpu_s - e16.cpu_s == pytest.approx(4 * 4800 * 48 * per_path)
    assert cost_model.estimate(big, s16).paths == 4 * e16.paths  # 4 cubes (2 views × 2 groups), 4× the pixels
    one_group = cost_model.estimate(_plan(tmp_path, (80, 60), groups=["lamp"]), s16)
    assert one_group.paths == e16.paths / 2 and one_group.kernel_s == e16.kernel_s / 2  # one light kind to build
    boosted = cost_model.estimate(small, RenderSettings(spp=16))  # the default 8× boost: more paths
    assert boosted.paths == pytest.approx(e16.paths * (1 + cost_model.boost_extra(RenderSettings(), 4800)))
    assert boosted.paths > 1.3 * e16.paths
    four = cost_model.estimate(small, s16, workers=4)
    assert four.kernel_s == 4 * e16.kernel_s and four.cpu_s > e16.cpu_s
    assert cost_model.estimate(small, RenderSettings(spp=16, backend="cycles")) is None
    assert set(e16.to_json()) == {"estimate_cpu_s", "estimate_wall_s", "estimate_machine"}


def test_estimate_of_the_measured_demo_is_close_to_what_was_measured():
    from illumix.scene.demo import demo_room

    p = jobs.plan([jobs.apply_resolution(demo_room(0), (64, 48))], None)
    e = cost_model.estimate(p, RenderSettings(spp=16))
    assert 0.7 * 27.2 < e.cpu_s < 1.3 * 27.2  # measured: 27.2 CPU s in a fresh process (cost_model docstring)
    assert "estimate" in e.line() and cost_model.MACHINE in e.line()


# -- the commands ---------------------------------------------------------------------------------
def test_render_dry_run_prints_an_estimate_and_its_json(tmp_path, capsys):
    cfg = tiny_scene_file(tmp_path)
    code, out, err = run_cli(capsys, "render", cfg, "--store", str(tmp_path / "st"), "--spp", "16", "--workers", "2",
                             "--dry-run", "--json")
    assert code == 0, err
    line = next(x for x in err.splitlines() if x.startswith("estimate: about "))
    assert "wall with 2 worker(s) for 6 job(s)" in line and "measured on a 2-vCPU" in line
    s = json.loads(out)
    assert s["estimate_cpu_s"] > 0 and s["estimate_wall_s"] > 0 and "2-vCPU" in s["estimate_machine"]


def test_dataset_dry_run_prints_an_estimate(tmp_path, capsys):
    from test_dataset import write_config

    cfg = write_config(tmp_path, {"name": "d", "scenes": [tiny_scene_file(tmp_path)],
                                  "render": {"spp": 16, "workers": 1}})
    code, out, err = run_cli(capsys, "dataset", cfg, "--store", str(tmp_path / "st"), "--dry-run", "--json")
    assert code == 0, err
    assert re.search(r"^estimate: about .* CPU, .* wall with 1 worker\(s\) for 6 job\(s\)", err, re.MULTILINE)
    assert json.loads(out.strip().splitlines()[-1])["estimate_cpu_s"] > 0


def _fake_run_job(delay: float):
    def run_job(payload, job, store_path, settings_dict, threads=None, overwrite=False):
        time.sleep(delay)
        return {"job": job.label, "kind": "cube" if job.group else "view", "seconds": delay, "cpu_s": delay}
    return run_job


def test_render_in_a_log_prints_a_line_per_job_and_heartbeats(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(jobs, "run_job", _fake_run_job(0.25))
    monkeypatch.setattr("illumix.render_run.HEARTBEAT_S", 0.1)
    code, _, err = run_cli(capsys, "render", tiny_scene_file(tmp_path), "--store", str(tmp_path / "st"),
                           "--spp", "4")
    assert code == 0, err
    lines = err.splitlines()
    assert lines[1].startswith("rendering 6 job(s) (2 view(s), 4 cube(s)) on 1 worker(s): a line per finished job")
    done = [x for x in lines if re.match(r"\[\d/6\] finished ", x)]
    assert len(done) == 6 and done[0].startswith("[1/6] finished mini/a/[view+aovs] in 0.2 s; 1/6 done, ")
    assert all(" per job" in x for x in done) and all("ETA" in x for x in done[:-1])
    beats = [x for x in lines if x.startswith("still rendering mini/")]
    assert beats and all(re.match(r"still rendering mini/\w/\S+: \d\.\d s, \d/6 done", x) for x in beats)


def test_dataset_in_a_log_reports_failures_as_lines(tmp_path, capsys, monkeypatch):
    from test_dataset import write_config

    ok = _fake_run_job(0.0)

    def run_job(payload, job, *a, **kw):
        if job.group == "bulb":
            raise RuntimeError("no bulb today")
        return ok(payload, job, *a, **kw)

    monkeypatch.setattr(jobs, "run_job", run_job)
    cfg = write_config(tmp_path, {"name": "d", "scenes": [tiny_scene_file(tmp_path)], "render": {"spp": 4}})
    code, _, err = run_cli(capsys, "dataset", cfg, "--store", str(tmp_path / "st"))
    assert code == 1
    assert "; 6/6 done (2 failed), " in err and re.search(r"^\[\d/6\] failed mini/a/bulb: RuntimeError: no bulb", err, re.MULTILINE)
    assert "[red]" not in err and err.count("failed mini/a/bulb") == 1


def test_json_runs_stay_quiet_and_a_terminal_keeps_the_bar(tmp_path, capsys, monkeypatch):
    from illumix.render_run import JobReport

    monkeypatch.setattr(jobs, "run_job", _fake_run_job(0.0))
    code, out, err = run_cli(capsys, "render", tiny_scene_file(tmp_path), "--store", str(tmp_path / "st"),
                             "--spp", "4", "--json")
    assert code == 0 and "finished" not in err and json.loads(out)["estimate_cpu_s"] > 0
    term = Console(file=io.StringIO(), force_terminal=True)
    report = JobReport(term, _plan(tmp_path), RenderSettings(spp=4), executor="local", workers=1, quiet=False)
    assert report.bar is not None and report.lines is None


def test_ray_executor_reports_each_job(tmp_path, capsys, monkeypatch):
    """run_ray calls on_done per finished task: the log gets a line per job (a synchronous fake Ray)."""
    from illumix.render_run import run_jobs

    class Ref:
        def __init__(self, value):
            self.value = value

    def remote(**_):
        return lambda fn: types.SimpleNamespace(remote=lambda *a: Ref(fn(*a)))

    fake = types.SimpleNamespace(is_initialized=lambda: True, remote=remote, put=lambda x: x, get=lambda r: r.value,
                                 wait=lambda refs, num_returns=1: (refs[:1], refs[1:]), cancel=lambda r: None,
                                 util=types.SimpleNamespace(get_node_ip_address=lambda: "10.0.0.7"))
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setattr("illumix.renderer_jobs.ray_executor.run_job", _fake_run_job(0.0))
    console = Console(stderr=True)
    done, failed = run_jobs(console, _plan(tmp_path), str(tmp_path / "st"), RenderSettings(spp=4), executor="ray",
                            workers=1, address=None, overwrite=False, quiet=False)
    err = capsys.readouterr().err
    assert len(done) == 6 and not failed and all(d["node"] == "10.0.0.7" for d in done)
    assert "on Ray: a line per finished job" in err and len(re.findall(r"^\[\d/6\] finished ", err, re.MULTILINE)) == 6


@needs_mitsuba
def test_a_tiny_real_render_logs_its_jobs(tmp_path, capsys):
    code, _, err = run_cli(capsys, "render", tiny_scene_file(tmp_path), "--store", str(tmp_path / "st"),
                           "--spp", "4", "--groups", "lamp")
    assert code == 0, err
    assert re.search(r"^estimate: about ", err, re.MULTILINE)
    assert len(re.findall(r"^\[\d/4\] finished mini/[ab]/", err, re.MULTILINE)) == 4 and "rendered 2 cube(s)" in err
