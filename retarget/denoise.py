"""Denoising of transport and illumination cubes that keeps relighting exact (DESIGN.md "Denoising").

Every method here is a *linear* operator ``D`` on a cube ``T (H, W, bands)`` whose weights are
computed from noise-free guides alone (the view's geometry AOVs: albedo, normal, depth, the hit and
emitter masks; its per-band albedo; the light group's direct light, traced with its own seeds),
never from the cube. ``D`` acts on every band with the same weights, so for every light group

    D(Σ_b s_b T_b) = Σ_b s_b D(T_b)      (relighting by any a Φ̄/Ē per band stays exact)

up to float32 rounding, and the service composes the groups' denoised cubes, so composition stays
exact too. The methods without a per-group guide are one operator for every group and commute with
the projection to camera raw as well (``P(D(T)) = D(P(T))``). The thesis' DT filter (§4.2) took its
edges from the image it filtered (a 5000-spp render), which makes it non-linear in the cubes; here
the domain transform's edges come from the guides.

Methods (case-insensitive registry :data:`retarget.denoise_methods.DENOISE_METHODS`, ``method="DT Guides"``):

- ``"dt-irradiance"`` (default, aliases ``"demodulated"``, ``"dt-demodulated"``): the transport
  cube divided band by band by the first hit's diffuse reflectance (the ``albedo_bands`` AOV) and
  by the group's direct light plus a floor for bounce light (:func:`retarget.denoise_shading.shading`),
  so what is filtered is nearly flat — smooth across material and texture edges (no colour can
  bleed: each pixel gets its own reflectance back after) and across a spot's falloff or a point
  light's ``cos/r²`` (a normalised filter bends a ramp where it stops); the domain transform's
  joint image is the normal, log depth and log of the group's *direct* light (``Guides.direct``):
  it stops at geometric edges and at the edges of shadows and sunlit patches, which no albedo or
  normal shows. Illumination cubes are irradiance already: filtered the same way without the
  albedo (``kind="illumination"``). Emitter and background pixels, surface pixels next to a light
  source or the sky behind a window, those glass shades from the group's light (a caustic may lie
  there), those straddling a geometric edge (the ``straddle`` AOV), in transport cubes metal and
  glass, and the pixels where the filter would move the guide's own light by more than the cube's
  noise (:func:`retarget.denoise_classes.direct_test`) are left as rendered
  (:func:`retarget.denoise_classes.irradiance_classes`). Measured in ``bench/DENOISE.md`` and, on
  scenes nobody tuned it on, ``bench/FIDELITY.md``.
- ``"dt-guides"`` (alias ``"dt"``): the domain-transform recursive filter (Gastal & Oliveira
  2011, "Domain Transform for Edge-Aware Image and Video Processing", eq. 21, three iterations) via
  OpenCV ``ximgproc.dtFilter``, joint image = 4 guide channels: albedo R, G, B / ``sigma_albedo`` and
  the normal's component along a fixed oblique axis / ``sigma_normal``. Emitter and background
  pixels are pushed far away in guide space, so they neither bleed nor receive light.
- ``"atrous-guides"`` (alias ``"atrous"``): edge-avoiding à-trous wavelet (Dammertz et al. 2010,
  "Edge-Avoiding À-Trous Wavelet Transform for fast Global Illumination Filtering") with weights
  from albedo, normal and relative depth only (no colour term); compact support (``levels`` of 5×5
  taps at strides 1, 2, 4, …), so a crop with a halo of ``2·(2^levels − 1)`` pixels filters exactly
  as the full frame does.

The last two see no illumination edge (a shadow's boundary on a flat wall): it is smoothed over by
``sigma_spatial``. ``bench/denoise.py`` measures that cost.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from illumix.retarget.denoise_classes import irradiance_classes
from illumix.retarget.denoise_filters import _FAR, _atrous, _dt, _dt_irradiance, dt_filter, dt_guide_image, irradiance_guide_image
from illumix.retarget.denoise_shading import relative_noise, shading
from illumix.retarget.denoise_methods import DEFAULT_METHOD, DENOISE_METHODS
from illumix.retarget.errors import SpectralError


@dataclass(frozen=True)
class Guides:
    """A view's denoising guides, all ``(H, W, …)`` float32/bool from the geometry AOV pass.

    albedo ``(H, W, 3)`` diffuse reflectance (R, G, B broad bands); normal ``(H, W, 3)`` unit world
    normal; depth ``(H, W)`` metres (0 = no hit); hit ``(H, W)`` bool; emitter ``(H, W)`` bool;
    albedo_bands ``(H, W, bands)`` diffuse reflectance per band (0 for metal and glass), or None;
    direct ``(H, W)`` one light group's direct light on a white Lambertian surface (any linear
    unit: only its log differences count), or None — a per-group guide, set with :meth:`with_direct`;
    behind_glass ``(H, W)`` the share of that group's direct light that only glass (a dielectric,
    crossed straight) keeps from the pixel, in [0, 1], or None: where the glass may focus the light
    (a caustic) the direct guide shows a shadow, so there it tells nothing; straddle ``(H, W)`` bool
    the pixel's sub-pixel rays hit more than one surface (the ``straddle`` AOV), or None;
    direct_noise ``(H, W)`` the standard error of ``direct`` (same unit), or None (taken as 0);
    cube_noise ``(H, W)`` the relative noise of the cube being denoised (:func:`relative_noise`,
    set with :meth:`with_cube_noise`), or None: then the direct-light test's tolerance is fixed;
    direct_seen ``(H, W)`` the group's direct light as the camera sees it through each surface's
    BSDF, per unit diffuse reflectance (a glossy highlight shows in it), or None.
    """

    albedo: np.ndarray
    normal: np.ndarray
    depth: np.ndarray
    hit: np.ndarray
    emitter: np.ndarray
    albedo_bands: np.ndarray | None = None
    direct: np.ndarray | None = None
    behind_glass: np.ndarray | None = None
    straddle: np.ndarray | None = None
    direct_noise: np.ndarray | None = None
    cube_noise: np.ndarray | None = None
    direct_seen: np.ndarray | None = None

    @classmethod
    def from_aovs(cls, aovs: Mapping[str, np.ndarray]) -> Guides:
        """From a view's AOVs (``albedo``, ``normal``, ``depth``; ``mask``, ``emitter``,
        ``albedo_bands`` and ``straddle`` optional)."""
        missing = [k for k in ("albedo", "normal", "depth") if k not in aovs]
        if missing:
            raise SpectralError(f"denoising needs the view's AOVs {missing}; re-render the view "
                                "(`illumix render … --overwrite`) to store them")
        depth = np.asarray(aovs["depth"], np.float32)
        hit = np.asarray(aovs["mask"], bool) if "mask" in aovs else depth > 0
        emitter = np.asarray(aovs["emitter"], bool) if "emitter" in aovs else np.zeros_like(hit)
        bands = np.asarray(aovs["albedo_bands"], np.float32) if "albedo_bands" in aovs else None
        straddle = np.asarray(aovs["straddle"], bool) if "straddle" in aovs else None
        return cls(np.asarray(aovs["albedo"], np.float32), np.asarray(aovs["normal"], np.float32),
                   depth, hit, emitter, bands, straddle=straddle)

    def with_direct(self, direct: np.ndarray, behind_glass: np.ndarray | None = None,
                    noise: np.ndarray | None = None, seen: np.ndarray | None = None) -> Guides:
        """These guides with a light group's direct-light image ``(H, W)`` (finite, ≥ 0) and, when
        given, the light that glass keeps from each pixel ``(H, W)`` (finite, ≥ 0, same unit as
        ``direct``: ``renderer_jobs.mitsuba.denoise_guides.direct_light(behind_glass=True)``), stored as
        the share ``behind / (behind + direct)``, and the direct image's standard error ``noise``
        ``(H, W)`` (finite, ≥ 0, same unit) and the light as the camera sees it ``seen`` ``(H, W)``
        (same unit: ``renderer_jobs.mitsuba.denoise_guides.direct_guide``)."""
        d = _checked_image(direct, self.shape, "direct-light guide")
        n = None if noise is None else _checked_image(noise, self.shape, "direct-light guide's noise")
        v = None if seen is None else _checked_image(seen, self.shape, "direct-light guide as seen")
        if behind_glass is None:
            return replace(self, direct=d, behind_glass=None, direct_noise=n, direct_seen=v)
        b = _checked_image(behind_glass, self.shape, "behind-glass guide")
        share = np.divide(b, b + d, out=np.zeros_like(b), where=(b + d) > 0)
        return replace(self, direct=d, behind_glass=share, direct_noise=n, direct_seen=v)

    def with_cube_noise(self, noise: np.ndarray | None) -> Guides:
        """These guides with the noise of the cube they will denoise: ``noise`` ``(H, W, 2)``, its
        band sum and that sum's variance (``renderer_jobs.mitsuba.band_render.set_noise``), or None."""
        if noise is None:
            return replace(self, cube_noise=None)
        a = np.asarray(noise, np.float32)
        if a.shape != (*self.shape, 2) or not np.isfinite(a).all():
            raise SpectralError(f"denoise: the cube's noise has shape {a.shape} or non-finite values; "
                                f"it must be finite, (H, W, 2) = {(*self.shape, 2)}")
        return replace(self, cube_noise=relative_noise(a[..., 0], a[..., 1]))

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth.shape[:2]

    def pixel_class(self) -> np.ndarray:
        """``(H, W)`` int8: 0 surface, 1 background (no hit), 2 emitter. Filters never mix classes."""
        return np.where(self.emitter, 2, np.where(self.hit, 0, 1)).astype(np.int8)


def _checked_image(image: np.ndarray, shape: tuple[int, int], what: str) -> np.ndarray:
    a = np.asarray(image, np.float32)
    if a.shape != shape:
        raise SpectralError(f"denoise: the {what} has shape {a.shape}; the view's is {shape}")
    if not np.isfinite(a).all() or (a < 0).any():
        raise SpectralError(f"denoise: the {what} has NaN, inf or negative values; it must be finite and >= 0 "
                            "(re-trace it: renderer_jobs.mitsuba.denoise_guides.direct_light)")
    return a


@dataclass(frozen=True)
class DenoiseMethod:
    """A registered method: its filter and default parameters (all overridable by keyword)."""

    run: Callable[..., np.ndarray]
    defaults: Mapping[str, Any]
    reference: str
    guides: tuple[str, ...] = ("albedo", "normal", "depth", "mask", "emitter")

    @property
    def per_group(self) -> bool:
        """Takes a guide of the light group's own (``direct``): one operator per group."""
        return "direct" in self.guides

    @property
    def demodulates(self) -> bool:
        """Divides a transport cube by the per-band albedo (``kind`` matters)."""
        return "albedo_bands" in self.guides


#: Implementation of every name of :data:`DENOISE_METHODS`.
IMPLEMENTATIONS: dict[str, DenoiseMethod] = {
    "dt-irradiance": DenoiseMethod(
        _dt_irradiance, {"sigma_spatial": 4.0, "sigma_normal": 0.05, "sigma_depth": 0.04, "sigma_direct": 0.4,
                         "albedo_floor": 0.01, "iterations": 3},
        "Gastal & Oliveira 2011 (domain transform, RF) on the albedo-demodulated cube, joint image from the "
        "normal, depth and the light group's direct light", ("albedo_bands", "normal", "depth", "mask", "emitter",
                                                            "straddle", "direct")),
    "dt-guides": DenoiseMethod(_dt, {"sigma_spatial": 4.0, "sigma_albedo": 0.05, "sigma_normal": 0.2, "iterations": 3},
                               "Gastal & Oliveira 2011 (domain transform, RF), joint image from AOV guides",
                               ("albedo", "normal", "mask", "emitter")),
    "atrous-guides": DenoiseMethod(_atrous, {"levels": 3, "sigma_albedo": 0.02, "sigma_normal": 0.05,
                                             "sigma_depth": 0.02},
                                   "Dammertz et al. 2010 (edge-avoiding a-trous), guide-only weights"),
}
assert set(IMPLEMENTATIONS) == set(DENOISE_METHODS.names)


def method_params(method: str, **params: Any) -> tuple[str, dict[str, Any]]:
    """``(canonical name, full parameter dict)``; an unknown parameter raises :class:`SpectralError`."""
    name = DENOISE_METHODS.canonical(method)
    defaults = IMPLEMENTATIONS[name].defaults
    unknown = set(params) - set(defaults)
    if unknown:
        raise SpectralError(f"denoise method {name!r} has no parameter(s) {sorted(unknown)}; "
                            f"it takes {', '.join(defaults)}")
    full = {**defaults, **params}
    for k, v in full.items():
        if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
            raise SpectralError(f"denoise parameter {k} must be a positive number, got {v!r}")
    return name, full


def denoise(cube: np.ndarray, guides: Guides, method: str = DEFAULT_METHOD, kind: str = "transport",
            **params: Any) -> np.ndarray:
    """Denoise a transport or illumination cube ``(H, W, bands)`` with guide-only weights; returns
    float32, same shape. ``kind``: ``"transport"`` or ``"illumination"`` (an illumination cube, or
    any ``(H, W, C)`` linear image of the view that carries no reflectance, e.g. per-group raw for
    the methods that do not demodulate).

    Linear in ``cube``, the same weights for every channel (module docstring). Raises
    :class:`SpectralError` for an unknown method/parameter, a shape that does not match the guides,
    or a guide the method needs and ``guides`` lacks (naming how to get it).
    """
    name, full = method_params(method, **params)
    impl = IMPLEMENTATIONS[name]
    arr = np.asarray(cube)
    if arr.ndim != 3 or arr.shape[:2] != guides.shape:
        raise SpectralError(f"denoise: cube shape {arr.shape} does not match the guides' {guides.shape} (H, W, C)")
    if not np.isfinite(arr).all():
        raise SpectralError("denoise: the cube has NaN or inf values")
    if kind not in ("transport", "illumination"):
        raise SpectralError(f"denoise: kind must be 'transport' or 'illumination', got {kind!r}")
    _check_guides(name, impl, guides, arr, kind)
    if impl.demodulates:
        full = {**full, "kind": kind}
    return _flush_tails(impl.run(arr, guides, **full))


def _check_guides(name: str, impl: DenoiseMethod, guides: Guides, arr: np.ndarray, kind: str) -> None:
    if guides.straddle is not None and guides.straddle.shape != guides.shape:
        raise SpectralError(f"denoise: the straddle guide {guides.straddle.shape} does not match the view's "
                            f"{guides.shape} (H, W); re-render the view's AOVs (`illumix render … --overwrite`)")
    if impl.per_group and guides.direct is None:
        raise SpectralError(f"denoise method {name!r} needs the light group's direct-light guide "
                            "(Guides.with_direct; the renderer traces it: renderer_jobs.mitsuba.denoise_guides), "
                            "or use method 'dt-guides'")
    if impl.demodulates and kind == "transport":
        bands = guides.albedo_bands
        if bands is None:
            raise SpectralError(f"denoise method {name!r} needs the view's 'albedo_bands' AOV; re-render the view "
                                "(`illumix render … --overwrite`), or use method 'dt-guides'")
        if bands.shape != arr.shape:
            raise SpectralError(f"denoise method {name!r} divides a transport cube by the per-band albedo "
                                f"{bands.shape}, which does not match the cube {arr.shape}; a cube without "
                                "reflectance (e.g. projected raw) is kind='illumination'")


def _flush_tails(out: np.ndarray) -> np.ndarray:
    """Zero values below 2⁻²⁴ of their pixel's largest channel, in place.

    Recursive filters leave exponentially decayed tails (1e-30 next to 1e-3) where the input was
    exactly zero; below float32 rounding of any band sum they change no projection, but a pixel
    spanning more than 2²⁹ would force the store's float16 encoding to fall back to float32.
    """
    top = np.abs(out).max(axis=-1, keepdims=True)
    out[np.abs(out) < top * np.float32(2.0 ** -24)] = 0.0
    return out


def as_rendered(guides: Guides, method: str = DEFAULT_METHOD, kind: str = "transport", **params: Any) -> np.ndarray | None:
    """``(H, W)`` bool: the pixels ``method`` leaves as rendered with these guides (every class code
    of ``dt-irradiance``'s joint image from 4 up: emitters, background, the direct-light test's…);
    None for a method that keeps no pixel apart by rule."""
    name, full = method_params(method, **params)
    if name != "dt-irradiance":
        return None
    joint = irradiance_guide_image(guides, full["sigma_normal"], full["sigma_depth"], full["sigma_direct"],
                                   full["albedo_floor"], kind, sigma_spatial=full["sigma_spatial"],
                                   iterations=int(full["iterations"]))
    return joint[..., 0] > 3.5 * _FAR  # codes ≥ 4 (the normal's part is at most 1/sigma_normal ≪ _FAR/2)


def method_guides(method: str) -> tuple[str, ...]:
    """The guides ``method`` reads: AOV names, and ``direct`` for a per-group direct-light guide
    (:meth:`Guides.with_direct`)."""
    return IMPLEMENTATIONS[DENOISE_METHODS.canonical(method)].guides


def describe(method: str, **params: Any) -> dict[str, Any]:
    """The metadata record of a denoising: method, parameters, guides and reference."""
    name, full = method_params(method, **params)
    return {"method": name, "params": full, "guides": list(IMPLEMENTATIONS[name].guides),
            "linear": True, "reference": IMPLEMENTATIONS[name].reference}


# dt_guide_image, irradiance_guide_image, relative_noise and shading are re-exported: callers import them from here
__all__ = ["DENOISE_METHODS", "DEFAULT_METHOD", "Guides", "as_rendered", "denoise", "describe", "dt_filter", "dt_guide_image",
           "irradiance_classes", "irradiance_guide_image", "method_guides", "method_params", "relative_noise", "shading"]
