"""A sun's light paths drawn through the windows (renderer_jobs/mitsuba/sun_windows.py) estimate
the cube camera paths do, and the until-clean rule gives daylight cubes with windows light rounds
(issue 39)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from illumix.renderer_jobs.render_settings import RenderSettings  # noqa: E402


def _yard() -> dict:
    """A floor and a back wall in the sun, seen by a camera, with a glass ball and two overlapping
    "windows" (sky portals of another group) floating above them: some sunlit points are reached by lines through
    no window, some through one, some through both — every branch of the line sampling counts."""
    from illumix.scene import demo

    shapes = [{"name": "floor", "type": "rectangle", "material": "white",
               "transform": {"matrix": demo.frame_matrix((0, 0, 0), (0, 1, 0), (0, 0, -1), (3, 3))}},
              {"name": "back", "type": "rectangle", "material": "white",
               "transform": {"matrix": demo.frame_matrix((0, 1, -1.5), (0, 0, 1), (0, 1, 0), (3, 2))}},
              {"name": "box", "type": "cube", "material": "white",
               "transform": {"matrix": [[0.2, 0, 0, 0.3], [0, 0.2, 0, 0.2], [0, 0, 0.2, -0.4], [0, 0, 0, 1]]}},
              {"name": "ball", "type": "sphere", "material": "glass", "center": (-0.45, 0.3, 0.1), "radius": 0.3}]
    for k, (c, size) in enumerate((((0.2, 1.6, -0.2), (0.8, 0.6)), ((-0.1, 1.9, -0.3), (0.6, 0.9)))):
        shapes.append({"name": f"window{k}", "type": "rectangle", "emitter": {"group": "sky", "strength": 1.0, "portal": True},
                       "transform": {"matrix": demo.frame_matrix(c, (0, -1, 0), (0, 0, -1), size)}})
    return {"name": "yard",
            "materials": {"white": {"kind": "diffuse", "reflectance": {"value": 0.6}},
                          "glass": {"kind": "dielectric", "int_ior": 1.5}},
            "shapes": shapes,
            "lights": [{"name": "sun", "type": "directional", "group": "sun", "direction": [0.25, -0.9, -0.3],
                        "strength": 3.0}],
            "light_groups": [{"name": "sun", "emission": "flat"}, {"name": "sky", "emission": "flat"}],
            "views": [{"name": "cam", "origin": (0, 1.2, 1.4), "target": (0, 0.3, -0.8), "fov": 70,
                       "resolution": (40, 30)}], "max_depth": 4}


def test_window_rects_are_the_portal_rectangles():
    from illumix.renderer_jobs.mitsuba.sun_windows import window_rects
    from illumix.scene.demo import demo_room
    from illumix.scene.load import scene_from_dict

    r = window_rects(scene_from_dict(_yard()))
    assert r.shape == (2, 4, 3)
    np.testing.assert_allclose(r[0, 0], (0.2, 1.6, -0.2))
    np.testing.assert_allclose(r[:, 3], [(0, -1, 0)] * 2, atol=1e-12)  # unit normals
    np.testing.assert_allclose(np.sort([np.linalg.norm(r[0, 1]), np.linalg.norm(r[0, 2])]), (0.3, 0.4))  # half sizes
    assert window_rects(demo_room(0, (32, 24))).shape == (1, 4, 3)
    d = _yard()
    d["shapes"] = d["shapes"][:3]
    d["light_groups"] = d["light_groups"][:1]
    assert window_rects(scene_from_dict(d)) is None


def test_crossings_count_the_windows_a_line_passes():
    from illumix.renderer_jobs.mitsuba.sun_windows import SunWindows, window_rects
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba
    from illumix.scene.load import scene_from_dict

    mi, dr = import_mitsuba()
    w = SunWindows(window_rects(scene_from_dict(_yard())))
    # vertical lines: through window 0 only, both, window 1 only, neither; a line in a window's plane
    x = [0.5, 0.0, -0.3, 1.2, 0.0]
    z = [-0.1, -0.3, -0.7, 0.0, -0.2]
    o = mi.Point3f(x, [5.0] * 4 + [1.6], z)
    d = mi.Vector3f([0.0] * 4 + [1.0], [-1.0] * 4 + [0.0], [0.0] * 5)
    assert list(np.asarray(w.crossings(mi, dr, o, d))) == [1, 2, 1, 0, 0]


def test_lines_through_windows_give_the_suns_flux_there_and_nothing_elsewhere():
    """The line sampling alone, against a closed form: over 2^20 sun paths, the weight of the lines
    landing in a patch of the ground is the flux the sun sends there, ``E · cos θ · area``, where its
    lines pass one window and where they pass both (counted once); where they pass none, nothing (camera
    paths take that part). Areas by a fine grid of those lines' own window counts."""
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene
    from illumix.renderer_jobs.mitsuba.sun_windows import SunWindows, window_rects
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba
    from illumix.scene.load import scene_from_dict

    mi, dr = import_mitsuba()
    yard = scene_from_dict(_yard())
    ms, _ = load_mitsuba_scene(yard, "cam", ["sun"], (40, 30), flat_emission=True)
    windows = SunWindows(window_rects(yard))
    n = 1 << 20
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(3, n)
    ray, weight, emitter = ms.sample_emitter_ray(0.0, sampler.next_1d(), sampler.next_2d(), sampler.next_2d(), True)
    ray, weight = windows.draw(mi, dr, ms, ray, weight, emitter, sampler)
    w = np.asarray(weight[0], np.float64) / float(mi.MI_CIE_MAX - mi.MI_CIE_MIN)
    o = np.stack([np.asarray(c, np.float64) for c in (ray.o.x, ray.o.y, ray.o.z)], -1)
    d = np.stack([np.asarray(c, np.float64) for c in (ray.d.x, ray.d.y, ray.d.z)], -1)
    sphere = ms.bbox().bounding_sphere()
    centre = np.array([sphere.center.x, sphere.center.y, sphere.center.z], np.float64)
    # every path starts outside the scene: whatever lies outside a window on its line is hit first
    assert np.all(np.linalg.norm(o - centre, axis=-1) >= 0.999 * float(sphere.radius))
    ground = o - d * (o[:, 1] / d[:, 1])[:, None]  # where each line meets y = 0
    k = np.asarray(windows.crossings(mi, dr, mi.Point3f(*ground.T), mi.Vector3f(*d.T)))
    # the same counts on a fine grid of the patch give each class's area
    g = np.linspace(-1.5, 1.5, 601)[:-1] + 0.0025
    gx, gz = (a.ravel() for a in np.meshgrid(g, g))
    d0 = d[0]
    kg = np.asarray(windows.crossings(mi, dr, mi.Point3f(gx, 0 * gx, gz), mi.Vector3f(*(np.ones((3, gx.size)) * d0[:, None]))))
    cos = abs(d0[1]) / np.linalg.norm(d0)
    inside = (np.abs(ground[:, 0]) < 1.5) & (np.abs(ground[:, 2]) < 1.5)
    for c in (0, 1, 2):
        area = (kg == c).mean() * 9.0
        assert area > 0.2, c  # every class is there to be measured
        x = w * (inside & (k == c))
        est, se = x.mean(), x.std() / np.sqrt(n)
        expected = 3.0 * cos * area if c else 0.0
        assert abs(est - expected) <= 4 * se + 0.01 * est, (c, est, expected, se)
    assert not np.any(w[k == 0])


def test_light_paths_through_windows_and_camera_paths_elsewhere_make_the_suns_whole_cube():
    """In the yard, where the sun lights the ground along lines through no window, one and two: light
    paths through the windows plus camera paths along the other lines (``sun_rest``) give the camera
    paths' cube over 4 seeds each — the whole frame, the ground in the windows' shadows and outside
    them, the glass ball (seen through it, the delta complement's alone: +11 % on the frame when the
    camera part counted it too) — and the illumination cube."""
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import emitter_passes, group_emission
    from illumix.scene.load import scene_from_dict

    yard = scene_from_dict(_yard())
    e = np.asarray(group_emission(yard, "sun")[0], np.float64)

    def renders(kind):
        st = [RenderSettings(denoise=None, seed=s, spp=32, clean_max_spp=0, resolution=(40, 30)) for s in range(1, 5)]
        return [render_all_bands(yard, "cam", ["sun"], emitter_passes(yard, ["sun"]), x, e, None, None, kind) for x in st]

    camera, light = renders("plain"), renders("light")
    assert light[0][2]["light_path_sets"] > 0 and light[0][2]["nonfinite_samples"] == 0
    for k in (0, 1):
        for rows, cols in ((slice(None), slice(None)), (slice(15, None), slice(20, None)), (slice(15, None), slice(0, 12)),
                           (slice(15, 27), slice(5, 17))):  # … and the glass ball
            mc = np.array([r[k][rows, cols].mean() for r in camera])
            ml = np.array([r[k][rows, cols].mean() for r in light])
            se = np.sqrt(mc.var(ddof=1) / 4 + ml.var(ddof=1) / 4)
            assert abs(mc.mean() - ml.mean()) < 4 * se + 2e-3 * mc.mean(), (k, rows, cols, mc, ml)


def test_a_suns_light_paths_through_a_window_estimate_the_camera_paths_cube():
    """End to end on the demo room (a sun through its window): over 4 seeds each, the sun pass's
    image means by light paths and by camera paths agree, cube and illumination."""
    from illumix.renderer_jobs.mitsuba.band_render import render_all_bands
    from illumix.renderer_jobs.mitsuba.render import group_emission
    from illumix.scene.demo import demo_room

    scene = demo_room(0, (48, 36))
    e = np.asarray(group_emission(scene, "daylight")[0], np.float64)

    def means(kind):
        out = []
        for seed in range(1, 5):
            st = RenderSettings(denoise=None, seed=seed, spp=32, clean_max_spp=0, resolution=(48, 36))
            r = render_all_bands(scene, scene.views[0].name, ["daylight"], ["without"], st, e, None, None, kind)
            assert (r[2]["light_path_sets"] > 0) == (kind == "light") and r[2]["nonfinite_samples"] == 0
            out.append((r[0].mean(), r[1].mean()))
        return np.array(out)

    camera, light = means("plain"), means("light")
    se = np.sqrt(camera.var(0, ddof=1) / 4 + light.var(0, ddof=1) / 4)
    assert np.all(np.abs(camera.mean(0) - light.mean(0)) < 4 * se + 1e-3 * camera.mean(0)), (camera, light)


def test_daylight_through_windows_takes_light_rounds_a_sun_without_windows_does_not(monkeypatch):
    """The demo room's daylight (a sun through its window): the rule's late rounds may take light
    paths, the sky portal's pass keeping to guided camera paths; a sun with no window keeps to
    camera paths."""
    from illumix.renderer_jobs.mitsuba import until_clean
    from illumix.renderer_jobs.mitsuba.band_render import light_paths_apply
    from illumix.renderer_jobs.mitsuba.render import render_cube
    from illumix.scene.demo import demo_room
    from illumix.scene.load import scene_from_dict

    scene = demo_room(0, (32, 24))
    assert light_paths_apply(scene, ["daylight"])
    yard = scene_from_dict(_yard())
    assert light_paths_apply(yard, ["sun"]) and not light_paths_apply(yard, ["sky"])  # sky portals: camera paths
    d = _yard()
    d["shapes"] = d["shapes"][:3]
    d["light_groups"] = d["light_groups"][:1]
    assert not light_paths_apply(scene_from_dict(d), ["sun"])
    monkeypatch.setattr(until_clean, "halves_clean", lambda m: False)
    st = RenderSettings(spp=16, clean_max_spp=64, denoise=None, illumination=False)
    r = render_cube(scene, scene.views[0].name, "daylight", st)
    assert r.stats["until_clean"]["kinds"][:3] == ["plain", "plain", "light"]
    assert r.stats["light_paths"] and r.stats["light_path_sets"] > 0
    assert r.stats["until_clean"]["guide"]  # learnt in the light round, for the sky portal's pass


def test_a_lamps_light_paths_are_the_same_with_windows_in_the_room():
    """Windows change only a sun's paths: a lamp's pass draws the same random numbers, so its light
    paths are the ones it takes in a room without windows."""
    from illumix.renderer_jobs.mitsuba.bands import band_quadruples
    from illumix.renderer_jobs.mitsuba.light_paths import light_set_aovs
    from illumix.renderer_jobs.mitsuba.scene_dict import load_mitsuba_scene
    from illumix.renderer_jobs.mitsuba.sun_windows import SunWindows, window_rects
    from illumix.scene.demo import demo_room

    scene = demo_room(0, (32, 24))
    ms, sensor = load_mitsuba_scene(scene, scene.views[0].name, ["desk"], (32, 24), flat_emission=True)
    quads, _ = band_quadruples(scene.spectral_grid.edges, np.arange(0, scene.spectral_grid.n_bands, 8))
    step, depth = scene.spectral_grid.step, scene.max_depth
    with_windows = light_set_aovs(quads, step, depth, True, ms, sensor, 8, 5, SunWindows(window_rects(scene)))
    np.testing.assert_allclose(with_windows, light_set_aovs(quads, step, depth, True, ms, sensor, 8, 5), rtol=1e-5, atol=1e-9)
