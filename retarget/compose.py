"""One sample, end to end: relight + project + ground truth + ISP (DESIGN.md, all equations).

This is what the service runs per request and what ``bench/compose.py`` times. Work a request does
not need is skipped: groups at zero intensity are not read, bands a group's weights zero out are not
multiplied, and outputs not asked for are not computed (the gain map needs weights; sRGB needs gain
and CCM maps).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from illumix.retarget import exposure as aec
from illumix.retarget import groundtruth as gt
from illumix.retarget.basis import BasisCube, project_groups_any
from illumix.retarget.ccm import fit_ccm
from illumix.retarget.errors import SpectralError
from illumix.retarget.isp import apply_ccm, encode_srgb
from illumix.retarget.relight import band_scales, raw_weights
from illumix.retarget.sensors import Sensor

OUTPUTS = ("raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture")
GT_OUTPUTS = frozenset(OUTPUTS) - {"raw"}  # everything the ground truth is computed for


@dataclass
class Composition:
    """Arrays of one sample (``None`` where not requested) plus scalars for metadata.

    raw ``(H, W, 3)``, gain ``(H, W, 3)``, ccm ``(H, W, 3, 3)``, srgb ``(H, W, 3)`` in [0, 1],
    weights ``(H, W, G)`` (eq. 3.3, always the formula's), mask ``(H, W)`` bool, illum ``(H, W, 3)``
    the per-pixel white point in camera RGB with G = 1 (LSMI's illumination map), mixture
    ``(H, W, G)`` each group's share of that white point's G; all float32 but the mask. ``gt`` names
    the ground truth that gain, ccm, srgb, illum and mixture follow. ``srgb_exposure``: the gain the
    sRGB rendering applied to ``ccm · (raw × gain)`` (its own constant AEC when no exposure was
    asked, else 1).
    """

    white_points: np.ndarray
    exposure_gain: float
    srgb_exposure: float = 1.0
    gt: str = "formula"
    raw: np.ndarray | None = None
    gain: np.ndarray | None = None
    ccm: np.ndarray | None = None
    srgb: np.ndarray | None = None
    weights: np.ndarray | None = None
    mask: np.ndarray | None = None
    illum: np.ndarray | None = None
    mixture: np.ndarray | None = None

    def outputs(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in OUTPUTS if getattr(self, k) is not None}


def group_ccms(sensor: Sensor, illuminants: np.ndarray, reflectances: np.ndarray) -> np.ndarray:
    """``(G, 3, 3)`` white-preserving CCMs, one per group illuminant (see :mod:`retarget.ccm`)."""
    return np.stack([fit_ccm(sensor.weights(), spd, reflectances, sensor.grid).matrix for spd in illuminants])


def compose(cubes: Sequence[np.ndarray | BasisCube], *, emissions: np.ndarray, illuminants: np.ndarray,
            intensities: np.ndarray, sensor: Sensor, ccms: np.ndarray | None = None,
            outputs: Iterable[str] = OUTPUTS, exposure: float | str | None = None,
            group_names: Sequence[str] | None = None,
            resize: Callable[[np.ndarray], np.ndarray] | None = None,
            skip_bands: bool = True, illumination: Sequence[np.ndarray] | None = None,
            valid: np.ndarray | None = None) -> Composition:
    """Compose one sample from per-group transport cubes.

    Ground truth (DESIGN.md "Ground truth"): without ``illumination`` the formula (thesis eq. 3.3):
    each pixel's white point mixes the groups' white points by their share of the raw's G. With
    ``illumination`` (one illumination cube per group, shaped like ``cubes``) the physical one: the
    per-pixel white point is the camera RGB of the relit illumination cubes,
    ``U_k = Σ_g Σ_i C_k (a Φ̄/Ē)_g(λ_i) U_g(λ_i) Δλ``; the mixture is each group's share of ``U_G``;
    ``gain_k = max_j U_j / U_k``; the CCM map mixes the groups' CCMs by that mixture. ``valid``:
    optional ``(H', W')`` bool of pixels where the ground truth is defined (geometry, not an emitter),
    and-ed into ``mask``.

    cubes : G arrays ``(H, W, n_bands)`` or :class:`retarget.basis.BasisCube` (spectrally compressed,
    projected in their K-dim subspace); emissions, illuminants : ``(G, n_bands)``;
    intensities : ``(G,)``; ccms : ``(G, 3, 3)`` (needed for ``ccm``/``srgb``).
    exposure : ``None`` leaves raw in relative units (sRGB then gets its own constant-M_min AEC),
    a number multiplies raw, ``"constant"``/``"adaptive"`` is the thesis AEC (eq. 4.2) on raw.
    resize : optional map of per-group raw ``(G, H, W, 3)`` → ``(G, H', W', 3)``. Projection is linear
    per pixel, so a linear (area/bilinear) resize of per-group raw equals resizing the cubes first,
    and the ground truth is then computed at the output resolution, consistent with its raw.
    skip_bands : leave out bands whose weights are zero for a group (exact; see
    :func:`retarget.relight.project_groups`).
    """
    want = _wanted(outputs, ccms)
    illuminants = np.atleast_2d(illuminants)
    intensities = np.asarray(intensities, dtype=np.float64).reshape(-1)
    wps = gt.lit_white_points(sensor.weights(), illuminants, intensities)
    scales = band_scales(illuminants, emissions, intensities, group_names, sensor.grid.wavelengths)
    group_raw = _project(cubes, scales, sensor, resize, skip_bands)
    raw, gain_exp = _exposed(group_raw.sum(axis=0), exposure)
    out = Composition(white_points=wps, exposure_gain=gain_exp)
    if "raw" in want:
        out.raw = raw
    if not (GT_OUTPUTS & want):
        return out
    weights = mask = None
    if illumination is None or "weights" in want:  # the physical ground truth needs no eq. 3.3 weights
        weights, mask = gt.illuminant_weights(group_raw[..., 1], prior=intensities)
    del group_raw
    out.weights = weights if "weights" in want else None
    if illumination is None:
        mixture, white = weights, (gt.mixed_white_point(weights, wps) if ({"gain", "srgb", "illum"} & want) else None)
    else:
        out.gt = "physical"
        mixture, white, mask = _physical(_project(illumination, scales, sensor, resize, skip_bands), intensities, wps)
    if valid is not None:
        mask = mask & valid
    out.mask = mask if "mask" in want else None
    out.mixture = mixture if "mixture" in want else None
    out.illum = white if "illum" in want else None
    _maps(out, want, raw, mixture, white, ccms, exposure)
    return out


def _wanted(outputs: Iterable[str], ccms: np.ndarray | None) -> set[str]:
    """The set of outputs asked for; :class:`SpectralError` for an unknown one, or for ``ccm``/``srgb``
    without CCMs."""
    want = set(outputs)
    unknown = want - set(OUTPUTS)
    if unknown:
        raise SpectralError(f"compose: unknown outputs {sorted(unknown)}; choose from {', '.join(OUTPUTS)}")
    if ({"ccm", "srgb"} & want) and ccms is None:
        raise SpectralError("compose: CCMs are needed for the ccm and srgb outputs")
    return want


def _project(cubes: Sequence[np.ndarray | BasisCube], scales: np.ndarray, sensor: Sensor,
             resize: Callable[[np.ndarray], np.ndarray] | None, skip_bands: bool) -> np.ndarray:
    """Per-group camera RGB ``(G, H', W', 3)`` float32 of transport (or illumination) cubes relit by
    ``scales``, resized by ``resize`` when given (see :func:`compose`)."""
    group = project_groups_any(cubes, raw_weights(scales, sensor.weights()), skip_bands=skip_bands)
    if resize is not None:
        group = np.ascontiguousarray(resize(group), dtype=np.float32)
    return group


def _exposed(raw: np.ndarray, exposure: float | str | None) -> tuple[np.ndarray, float]:
    """``(raw × the exposure gain (in place), that gain)``: 1 for ``None``, the thesis AEC (eq. 4.2)
    on raw for ``"constant"``/``"adaptive"``, else the positive number given."""
    if exposure is None or isinstance(exposure, str):
        gain_exp = 1.0 if exposure is None else aec.aec_gain(raw, method=exposure)
    else:
        gain_exp = float(exposure)
        if not (np.isfinite(gain_exp) and gain_exp > 0):
            raise SpectralError(f"compose: exposure must be a positive number, got {exposure}")
    if gain_exp != 1.0:
        raw *= np.float32(gain_exp)
    return raw, gain_exp


def _physical(group_u: np.ndarray, intensities: np.ndarray,
              wps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The physical ground truth ``(mixture, white, mask)`` from the groups' illumination cubes in
    camera RGB ``group_u`` ``(G, H, W, 3)`` (DESIGN.md "Ground truth")."""
    mixture, mask = gt.illuminant_weights(group_u[..., 1], prior=intensities)  # lit, even if black
    white, mask = gt.physical_white_point(group_u.sum(axis=0), mask, gt.mixed_white_point(mixture, wps))
    return mixture, white, mask


def _maps(out: Composition, want: set[str], raw: np.ndarray, mixture: np.ndarray, white: np.ndarray | None,
          ccms: np.ndarray | None, exposure: float | str | None) -> None:
    """Fill in ``out``'s gain and CCM maps and its sRGB rendering, those of them ``want`` asks for."""
    gain = gt.gain_map(white) if ({"gain", "srgb"} & want) else None
    ccm = gt.ccm_map(mixture, ccms) if ({"ccm", "srgb"} & want) else None
    out.gain = gain if "gain" in want else None
    out.ccm = ccm if "ccm" in want else None
    if "srgb" in want:
        # one CCM pass: the AEC of the sRGB rendering measures the very image it then encodes
        linear = apply_ccm(raw * gain, ccm)
        if exposure is None:
            out.srgb_exposure = float(aec.aec_gain(linear, method="constant"))
            linear *= np.float32(out.srgb_exposure)
        out.srgb = encode_srgb(linear)
