"""Validation of the renderer against closed form (the analogue of thesis §5.1, Tables 5.1/5.2).

A ColorChecker Classic of 24 Lambertian patches (``ColorChecker N Ohta`` reflectances ``S̄``) lies in
the plane z = 0 facing a camera on its axis; one directional light of unit irradiance (on a plane
perpendicular to it) arrives at angle θ from the normal; nothing else is in the scene. The radiance
of a patch is then ``S̄ · E · cosθ / π`` per band, and its camera raw under illuminant ``Φ`` is

    R_k = Σ_i C_k(λ_i) · Φ̄(λ_i) / Ē(λ_i) · S̄(λ_i) · E · cosθ / π · Δλ       (E = 1, Ē = flat = 1)

The renderer path: one transport cube with flat unit emission, relit by ``Φ̄/Ē`` (DESIGN.md "The key
idea"), projected through ``C``, averaged over each patch's interior (the central ``interior``
fraction of the patch, in pixels). Compared per illuminant and patch:

- ``relative_rg_bg_pct`` (thesis eq. 4.1) and ``angular_deg`` (eq. 5.1) on raw;
- ``delta_e00``: both raws white-balanced by the illuminant's sensor white point (eq. 3.2) and
  normalised so the perfect white is (1, 1, 1), mapped to linear sRGB by the sensor × illuminant CCM
  (white preserving, fitted on the ColorChecker), brightness-equalised on the mean green of all
  patches (as in §5.1), converted to CIELAB (D65) and compared with CIEDE2000.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import colour
import numpy as np

from illumix.scene import demo
from illumix.scene.model import Scene

DEFAULT_ILLUMINANTS = ("D65", "A", "FL2", "FL11", "FL12", "blackbody:2300")
DEFAULT_SENSOR = "Nikon 5100 (NPL)"
VIEW = "head-on"
GROUP = "light"


def pixel_of(scene: Scene, view: str, point) -> tuple[float, float]:
    """Continuous pixel coordinates ``(x, y)`` (origin top-left) of a world point in a view.

    Pinhole with horizontal field of view ``fov`` (Mitsuba's ``perspective`` with ``fov_axis = x``).
    """
    v = scene.view(view)
    w, h = v.resolution
    o, t, up = (np.asarray(a, dtype=float) for a in (v.origin, v.target, v.up))
    d = (t - o) / np.linalg.norm(t - o)
    r = np.cross(d, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, d)
    q = np.asarray(point, dtype=float) - o
    z = q @ d
    tx = math.tan(math.radians(v.fov) / 2)
    ty = tx * h / w
    return ((q @ r) / z / tx + 1) / 2 * w, (1 - (q @ u) / z / ty) / 2 * h


def patch_masks(scene: Scene, interior: float = 0.6) -> np.ndarray:
    """``(24, H, W)`` bool: pixels whose centres lie in the central ``interior`` fraction of each patch
    of the validation chart. Raises ``ValueError`` when a patch interior holds no pixel."""
    v = scene.view(VIEW)
    w, h = v.resolution
    centers = demo.chart_patch_centers((0, 0, 0), (0, 0, 1), (0, 1, 0), demo.VALIDATION_PATCH, demo.VALIDATION_GAP)
    half = demo.VALIDATION_PATCH / 2 * interior
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    out = np.zeros((24, h, w), dtype=bool)
    for i, c in enumerate(centers):
        x0, y0 = pixel_of(scene, VIEW, c + np.array([-half, half, 0]))
        x1, y1 = pixel_of(scene, VIEW, c + np.array([half, -half, 0]))
        out[i] = (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)
        if not out[i].any():
            raise ValueError(f"patch {i + 1} covers no whole pixel at {w}x{h}; use a higher resolution")
    return out


@dataclass
class ValidationResult:
    patches: list[dict]
    summary: list[dict]
    meta: dict

    def to_dict(self) -> dict:
        return {"patches": self.patches, "summary": self.summary, **self.meta}


def closed_form_radiance(scene: Scene, incidence_deg: float) -> np.ndarray:
    """``(24, n_bands)``: band-average radiance ``S̄ · E · cosθ / π`` of each patch (E = 1)."""
    from illumix.retarget.reflectances import get_reflectances

    _, refl = get_reflectances(demo.CHART_SET, scene.spectral_grid)
    return refl * math.cos(math.radians(incidence_deg)) / math.pi


def compare(patch_radiance: np.ndarray, scene: Scene, sensor, illuminant: str, incidence_deg: float,
            emission: np.ndarray) -> list[dict]:
    """Per-patch metrics for one illuminant from rendered mean band radiance ``(24, n_bands)``."""
    from illumix.retarget import metrics
    from illumix.retarget.ccm import fit_ccm, linear_srgb_to_lab
    from illumix.retarget.groundtruth import white_point
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.reflectances import get_reflectances
    from illumix.retarget.relight import band_scales

    grid = scene.spectral_grid
    phi = illuminant_spd(illuminant, grid)
    cw = sensor.weights()
    scale = band_scales(phi[None], emission[None], np.ones(1))[0]
    raw_r = (patch_radiance * scale) @ cw
    raw_c = (closed_form_radiance(scene, incidence_deg) * phi) @ cw
    white = (phi * math.cos(math.radians(incidence_deg)) / math.pi) @ cw
    wp = white_point(cw, phi, what=illuminant)
    _, train = get_reflectances(demo.CHART_SET, grid)
    ccm = fit_ccm(cw, phi, train, grid).matrix

    def to_lab(raw: np.ndarray, gain: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        balanced = raw / wp / white[1]
        lin = balanced @ ccm.T * gain
        return lin, linear_srgb_to_lab(lin)

    lin_c, lab_c = to_lab(raw_c)
    lin_r, _ = to_lab(raw_r)
    bright = float(lin_c[:, 1].mean() / lin_r[:, 1].mean())
    _, lab_r = to_lab(raw_r, bright)
    de = np.asarray(colour.delta_E(lab_c, lab_r, method="CIE 2000"))
    rel = metrics.relative_rg_bg(raw_c, raw_r)
    ang = metrics.angular_error(raw_c, raw_r)
    return [{"illuminant": illuminant, "patch": i + 1, "delta_e00": float(de[i]),
             "relative_rg_bg_pct": float(rel[i]), "angular_deg": float(ang[i]),
             "raw_rendered": [float(x) for x in raw_r[i]], "raw_closed_form": [float(x) for x in raw_c[i]],
             "brightness_gain": bright} for i in range(24)]


def run_validation(sensor: str = DEFAULT_SENSOR, illuminants=DEFAULT_ILLUMINANTS, *, spp: int = 64, seed: int = 0,
                   resolution: tuple[int, int] = (192, 128), incidence_deg: float = 30.0,
                   interior: float = 0.6, wavelengths: str = "stratified",
                   backend: str = "mitsuba") -> ValidationResult:
    """Render the validation chart once (with ``backend``: ``"mitsuba"`` or ``"cycles"``) and compare
    it with closed form under every illuminant."""
    from illumix.renderer_jobs.mitsuba import render as mr
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.retarget.sensors import get_sensor

    scene = demo.validation_chart(resolution=resolution, incidence_deg=incidence_deg)
    sen = get_sensor(sensor, scene.spectral_grid)
    for name in illuminants:  # fail on a bad name before rendering
        illuminant_spd(name, scene.spectral_grid)
    masks = patch_masks(scene, interior)
    settings = mr.RenderSettings(spp=spp, seed=seed, wavelengths=wavelengths, backend=backend, illumination=False)
    from illumix.renderer_jobs.backends import get_backend

    res = get_backend(settings.backend).render_cube(scene, VIEW, GROUP, settings)
    cube = res.cube.astype(np.float64)
    radiance = np.stack([cube[m].mean(axis=0) for m in masks])
    patches: list[dict] = []
    summary: list[dict] = []
    for name in illuminants:
        rows = compare(radiance, scene, sen, name, incidence_deg, res.emission)
        patches += rows
        de = np.array([r["delta_e00"] for r in rows])
        summary.append({"illuminant": name, "mean_delta_e00": float(de.mean()), "max_delta_e00": float(de.max()),
                        "mean_relative_rg_bg_pct": float(np.mean([r["relative_rg_bg_pct"] for r in rows])),
                        "mean_angular_deg": float(np.mean([r["angular_deg"] for r in rows])),
                        "low_le_3": int((de <= 3).sum()), "medium_3_9": int(((de > 3) & (de < 9)).sum()),
                        "high_ge_9": int((de >= 9).sum())})
    meta = {"sensor": sen.name, "illuminants": list(illuminants), "spp": spp, "seed": seed,
            "resolution": list(resolution), "incidence_deg": incidence_deg, "interior_fraction": interior,
            "pixels_per_patch": [int(m.sum()) for m in masks], "wavelength_sampling": wavelengths,
            "backend": settings.backend,
            "renderer": res.renderer, "render_seconds": res.stats["total_s"],
            "reflectances": demo.CHART_SET, "grid": scene.spectral_grid.to_dict()}
    return ValidationResult(patches=patches, summary=summary, meta=meta)
