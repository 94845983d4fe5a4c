"""Renderer backends behind one protocol (renderer_jobs/backends.py, issue 34): the registry, and a
second renderer added by one module and one registry entry (this file's FakeBackend)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from illumix.renderer_jobs import jobs, modes
from illumix.renderer_jobs.backends import JobBackend, get_backend
from illumix.renderer_jobs.execute import execute
from illumix.renderer_jobs.modes import BACKENDS, EXECUTORS, BackendEntry
from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scene.load import scene_from_dict
from illumix.retarget.errors import UnknownName
from test_render_cli import tiny_scene_file


def test_every_registered_backend_implements_the_protocol():
    for name in BACKENDS.names:
        b = get_backend(name)
        assert b.name == name and set(b.executors) <= set(EXECUTORS.names)
        assert callable(b.require) and callable(b.render_cube)
        assert callable(getattr(b, "run_job", None)) or callable(getattr(b, "run", None))
    assert get_backend("Blender").name == "cycles"
    with pytest.raises(UnknownName, match="mitsuba"):
        get_backend("mitsuaba")


class FakeBackend(JobBackend):
    """A renderer that lights every pixel with 1/(group number): enough to go through the store."""

    name = "fake"
    executors = ("local",)

    def require(self) -> None:
        pass

    def render_cube(self, scene, view, group, settings):
        from illumix.renderer_jobs.mitsuba.render import CubeResult

        v = scene.view(view)
        n = scene.spectral_grid.n_bands
        value = 1.0 / (1 + scene.group_names.index(group))
        return CubeResult(cube=np.full((v.height, v.width, n), value, np.float32), emission=np.ones(n),
                          emission_name="flat", renderer={"name": "fake", "version": "0"})

    def run_job(self, payload, job, store_path, settings_dict, threads=None, overwrite=False):
        scene = jobs._scene_from_payload(payload)
        settings = RenderSettings(**settings_dict)
        st = jobs._open_store(store_path, mode="a")
        if job.group is None:
            st.write_view(scene.name, job.view, jobs._view_meta(scene, job.view))
        else:
            jobs.store_result(st, scene, job, self.render_cube(scene, job.view, job.group, settings), settings,
                              overwrite, {})
        return {"job": job.label, "seconds": 0.0, "kind": "view" if job.group is None else "cube"}


BACKEND = FakeBackend()


def test_a_second_renderer_is_one_module_and_one_registry_entry(tmp_path, monkeypatch):
    registry = modes.MethodRegistry("render backend", {**{n: BACKENDS[n] for n in BACKENDS.names},
                                                        "fake": BackendEntry("a test renderer", __name__)})
    monkeypatch.setattr(modes, "BACKENDS", registry)
    monkeypatch.setattr("illumix.renderer_jobs.backends.BACKENDS", registry)
    from illumix.store import CubeStore

    scene = scene_from_dict(yaml.safe_load(open(tiny_scene_file(tmp_path))))
    store = str(tmp_path / "st")
    settings = RenderSettings(backend="fake", denoise="none", skip_dark=False, boost_factor=1)
    done = execute(jobs.plan([scene], store), store, settings)
    assert len(done) == 6
    st = CubeStore.open(store, mode="r")
    for i, g in enumerate(scene.group_names):
        cube = st.read_cube(scene.name, "a", g)
        np.testing.assert_allclose(cube, 1.0 / (1 + i), rtol=1e-3)
        assert st.cube_meta(scene.name, "a", g).renderer.name == "fake"
    with pytest.raises(Exception, match="executors local"):
        execute(jobs.plan([scene], str(tmp_path / "other")), str(tmp_path / "other"), settings, executor="ray")
