"""A small synthetic store for service and client tests: real CubeStore, analytic transport cubes.

Scene ``synth`` / view ``v0`` (48×64): the left half holds ColorChecker patches, the right half a
spectrally flat 50 % gray; group ``window`` falls off left→right, group ``lamp`` right→left; the
bottom 4 rows get no light from either group (validity mask must be False there). Both cubes have
flat unit emission. Scene ``synth`` / view ``solo`` has one group. Scene ``thesis`` / view ``v0`` has
one group rendered with an emission that is zero above 650 nm (relighting by D65 must be refused).
"""

from __future__ import annotations

import numpy as np

from illumix.retarget.grid import DEFAULT_GRID
from illumix.retarget.reflectances import get_reflectances

H, W = 48, 64
DARK_ROWS = 4


def reflectance_image(h: int = H, w: int = W) -> np.ndarray:
    """``(h, w, bands)``: ColorChecker tiles (6×4 patches of 8×8) on the left, 50 % gray right."""
    _, cc = get_reflectances("ColorChecker N Ohta")
    n = DEFAULT_GRID.n_bands
    refl = np.full((h, w, n), 0.5, dtype=np.float32)
    p = min(h // 6, w // 8)
    for i in range(24):
        r, c = divmod(i, 4)
        refl[r * p:(r + 1) * p, c * p:(c + 1) * p] = cc[i]
    return refl


def falloffs(h: int = H, w: int = W) -> tuple[np.ndarray, np.ndarray]:
    x = np.linspace(0.0, 1.0, w)
    window = np.tile(0.05 + 0.95 * (1 - x) ** 2, (h, 1)).astype(np.float32)
    lamp = np.tile(0.05 + 0.95 * x ** 2, (h, 1)).astype(np.float32)
    window[-DARK_ROWS:] = 0
    lamp[-DARK_ROWS:] = 0
    return window, lamp


def build(path, h: int = H, w: int = W, extras: bool = True, illumination: bool = False,
          denoised: bool = False, storage_options: dict | None = None) -> None:
    """Write the synthetic scenes into a store at ``path`` (``extras``: the solo and thesis views).

    ``illumination``: also store the illumination cubes of synth/v0 (a white Lambertian under each
    group: ``falloff/π`` in every band, so the transport cube is exactly reflectance × illumination),
    and the view's hit mask (all geometry) and emitter AOV (an "emitter" in the top-left 2×2).
    ``denoised`` (implies ``illumination``): synth/v0's cubes carry 10 % noise per band (seeded) and
    their copies denoised with the default method are stored beside them."""
    from illumix.store import CubeMeta, CubeStore, ViewMeta

    st = CubeStore.open(str(path), mode="a", storage_options=storage_options)
    refl = reflectance_image(h, w)
    fw, fl = falloffs(h, w)
    n = DEFAULT_GRID.n_bands
    flat = [1.0] * n
    common = dict(grid=DEFAULT_GRID.to_dict(), renderer={"name": "synthetic", "version": "1"},
                  spp=0, seed=0, scene_hash="synthetic")
    aovs = None
    illumination = illumination or denoised
    if illumination:
        emitter = np.zeros((h, w), bool)
        emitter[:2, :2] = True
        aovs = {"mask": np.ones((h, w), bool), "emitter": emitter,
                "albedo": refl[..., [50, 30, 10]].astype(np.float32),
                "normal": np.broadcast_to(np.float32([0, 0, 1]), (h, w, 3)).copy(),
                "depth": np.full((h, w), 2.0, np.float32), "albedo_bands": refl.astype(np.float32)}
    st.write_view("synth", "v0", ViewMeta(width=w, height=h, fov=45.0), aovs)
    rng = np.random.default_rng(11)
    for name, f in (("window", fw), ("lamp", fl)):
        u = np.broadcast_to((f / np.float32(np.pi))[..., None], refl.shape).astype(np.float32)
        meta = CubeMeta(emission=flat, emission_name="flat", **common)
        cube, copies = refl * u, None
        if denoised:
            from illumix.retarget.denoise import DEFAULT_METHOD, Guides, denoise, describe
            from illumix.store.schema import DenoisedInfo

            noisy = [(x * (1 + 0.1 * rng.standard_normal(x.shape))).astype(np.float32) for x in (cube, u)]
            cube, u = noisy
            guides = Guides.from_aovs(aovs).with_direct(f)  # this group's light (all of it direct here)
            copies = {"transport": denoise(cube, guides), "illumination": denoise(u, guides, kind="illumination")}
            meta.denoised = DenoisedInfo(**describe(DEFAULT_METHOD))
        st.write_cube("synth", "v0", name, cube, meta, illumination=u if illumination else None, denoised=copies)
    if not extras:
        return
    st.write_view("synth", "solo", ViewMeta(width=w, height=h, fov=45.0))
    st.write_cube("synth", "solo", "lamp", (refl * fl[..., None] / np.pi).astype(np.float32),
                  CubeMeta(emission=flat, emission_name="flat", **common))
    cut = (DEFAULT_GRID.wavelengths <= 650).astype(float).tolist()
    st.write_view("thesis", "v0", ViewMeta(width=w, height=h, fov=45.0))
    st.write_cube("thesis", "v0", "booth", (refl * fw[..., None] * np.array(cut) / np.pi).astype(np.float32),
                  CubeMeta(emission=cut, emission_name="cut650", **common))
