"""A small store for the export tests: the synthetic store (tests/synthetic_store.py, with
illumination cubes) plus four more two-group scenes (names with ``_``, for the place-name rule and
the splits), one of whose views has a ColorChecker Classic in its albedo AOV under a known
homography (for the chart finder)."""

from __future__ import annotations

import numpy as np
import synthetic_store as syn

CHART_SCENE = "room_chart"
CHART_SIZE = (128, 96)  # the chart view is larger than the others: ~14 px patches
# chart coordinates (patch pitches, 6 × 4) → image pixels of the 128 × 96 frame: a perspective view
CHART_H = np.array([[17.2, 2.4, 10.0], [-1.2, 15.6, 12.0], [0.001, 0.002, 1.0]])


def chart_albedo(h: int = CHART_SIZE[1], w: int = CHART_SIZE[0], hom: np.ndarray = CHART_H, s: int = 24) -> np.ndarray:
    """``(h, w, 3)`` albedo: 0.5 gray with a ColorChecker (patches 0.8 pitch wide on a 0.04 board)
    warped in by ``hom``; nearest-neighbour, so each patch holds its exact broad-band albedo."""
    import cv2

    from illumix.dataset_export.chart import COLS, ROWS, chart_albedos

    ref = chart_albedos(3)
    chart = np.full((ROWS * s, COLS * s, 3), 0.04, np.float32)
    for i, r in enumerate(ref):
        row, col = divmod(i, COLS)
        chart[int((row + 0.1) * s):int((row + 0.9) * s), int((col + 0.1) * s):int((col + 0.9) * s)] = r
    out = np.full((h, w, 3), 0.5, np.float32)
    warp = hom @ np.diag([1 / s, 1 / s, 1])
    return cv2.warpPerspective(chart, warp, (w, h), dst=out, flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_TRANSPARENT)


def chart_corners(hom: np.ndarray = CHART_H) -> np.ndarray:
    import cv2

    from illumix.dataset_export.chart import OUTLINE

    return cv2.perspectiveTransform(OUTLINE[None], hom)[0]


def build_export_store(path) -> str:
    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.store import CubeMeta, CubeStore, ViewMeta

    syn.build(path, illumination=True)
    st = CubeStore.open(str(path), mode="a")
    common = dict(grid=DEFAULT_GRID.to_dict(), renderer={"name": "synthetic", "version": "1"}, spp=0, seed=0,
                  scene_hash="synthetic", emission=[1.0] * DEFAULT_GRID.n_bands, emission_name="flat")
    for k, scene in enumerate(["room_1", "room_2", "room_3", CHART_SCENE]):
        w, h = CHART_SIZE if scene == CHART_SCENE else (syn.W, syn.H)
        refl = syn.reflectance_image(h, w)
        fw, fl = syn.falloffs(h, w)
        aovs = {"mask": np.ones((h, w), bool), "emitter": np.zeros((h, w), bool)}
        if scene == CHART_SCENE:
            aovs["albedo"] = chart_albedo()
        st.write_view(scene, "v0", ViewMeta(width=w, height=h, fov=45.0), aovs)
        for name, f in (("window", fw * (1 + 0.2 * k)), ("lamp", fl)):
            u = np.broadcast_to((f / np.float32(np.pi))[..., None], refl.shape).astype(np.float32)
            st.write_cube(scene, "v0", name, refl * u, CubeMeta(**common), illumination=u)
    return str(path)
