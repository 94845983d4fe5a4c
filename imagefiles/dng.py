"""DNG raw files (Adobe DNG 1.4) written with pidng, read by libraw (``rawpy``).

A frame is stored as the sensor recorded it — a Bayer colour-filter-array mosaic (``CFAPattern``
RGGB/BGGR/GRBG/GBRG; ``(H, W)``) — or, without a pattern, as a linear raw (``PhotometricInterpretation``
34892 LinearRaw, three samples R, G, B per pixel, interleaved; ``(H, W, 3)``: the camera RGB before
any demosaicing, which libraw opens as a ``Stack`` raw whose ``raw_image[..., :3]`` is the frame).
16 bits per sample, with ``BlackLevel`` / ``WhiteLevel`` of the export's sensor model, and the
camera's colour as DNG expects it:

- ``ColorMatrix1`` (``CalibrationIlluminant1`` = D65): XYZ → camera RGB under D65. From the sensor's
  spectral sensitivities: illumix's D65 CCM ``M`` (white-balanced camera → linear sRGB, white
  preserving, fitted on the ColorChecker by :func:`retarget.ccm.fit_ccm`) gives
  ``XYZ = A_sRGB→XYZ · M · diag(1/ρ_w) · camera`` with ``ρ_w = Σ_λ C(λ) S_D65(λ) Δλ`` the camera's
  D65 white, so ``ColorMatrix1 = diag(ρ_w) · M⁻¹ · A_sRGB→XYZ⁻¹``, scaled so that D65's white
  (Y = 1) maps to a camera value whose largest channel is 1 (the DNG specification's normalisation);
- ``AsShotNeutral``: the ground-truth white point of the frame in camera RGB (G = 1) — the
  illuminant's white point for a single-light frame, the mean of the mixed illumination map for a
  multi-light one (:func:`as_shot_neutral`). libraw's ``camera_whitebalance`` is its inverse.

Used by ``illumix export --format dng`` (:mod:`dataset_export.raw_layout`) and ``GET /sample?format=dng``
(:mod:`service.file_downloads`).

Rationals are written with denominator 10⁶ (6 significant decimals; the tests check to 1e-5).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.global_wb import frame_white_point
from illumix.retarget.sensor_model import NoiseModel

DENOMINATOR = 1_000_000
DNG_MIN_SIDE = 22  # libraw refuses smaller DNGs ("Unsupported file format")
DNG_LEVELS = NoiseModel()  # the default levels of noise-free frames (black 64, white 4095)


def color_matrix(sensor_weights: np.ndarray, spd_d65: np.ndarray, ccm_d65: np.ndarray) -> np.ndarray:
    """``(3, 3)`` ColorMatrix1 (XYZ → camera under D65), see the module docstring.

    sensor_weights : ``(bands, 3)`` ``C_k Δλ``; spd_d65 : ``(bands,)``; ccm_d65 : ``(3, 3)`` white-balanced
    camera → linear sRGB."""
    import colour

    rho = np.asarray(spd_d65, np.float64) @ np.asarray(sensor_weights, np.float64)
    srgb_to_xyz = colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ
    cm = np.diag(rho) @ np.linalg.inv(np.asarray(ccm_d65, np.float64)) @ np.linalg.inv(srgb_to_xyz)
    white = srgb_to_xyz @ np.ones(3)  # D65, Y = 1
    return cm / np.max(cm @ white)


def as_shot_neutral(white_points, mixture: np.ndarray | None = None, valid: np.ndarray | None = None
                    ) -> list[float]:
    """A frame's as-shot neutral in camera RGB (G = 1), the ground-truth white point.

    One light (``mixture`` ``None``): its white point. Mixed light: the mean over the ``valid`` pixels
    of LSMI's illumination map ``Σ_i mixture_i · white_i`` (= the mean of the service's ``illum``
    output for ``gt=formula``) — the lights' white points weighted by their mean mixture share, the
    thesis' single global white point (:mod:`retarget.global_wb`, the web explorer's baseline);
    equal shares where no pixel is valid.

    white_points : ``(k, 3)`` camera RGB (G = 1) of the lit lights; mixture : ``(H, W, k)`` their
    shares; valid : ``(H, W)`` bool."""
    c = np.asarray(white_points, np.float64)
    if mixture is None:
        return c[0].tolist()
    return frame_white_point(mixture, valid, c).tolist()


def _rationals(values) -> list[list[int]]:
    return [[round(float(v) * DENOMINATOR), DENOMINATOR] for v in np.ravel(values)]


def noise_profile(model: NoiseModel) -> tuple[float, float]:
    """DNG ``NoiseProfile`` ``(S, O)`` of a sensor model: the variance of a signal ``x`` normalised to
    [0, 1] is ``S·x + O`` — shot noise ``S = 1/full_well``, read noise ``O = (read_noise/full_well)²``."""
    return 1.0 / model.full_well, (model.read_noise / model.full_well) ** 2


def dng_bytes(image: np.ndarray, *, black: int, white: int, pattern: str | None, matrix: np.ndarray,
              neutral, model: str, description: str = "", noise: tuple[float, float] | None = None) -> bytes:
    """A DNG of ``image`` uint16 (module docstring): a Bayer mosaic ``(H, W)`` with ``pattern`` (e.g.
    ``"RGGB"``), or a LinearRaw ``(H, W, 3)`` RGB frame with ``pattern=None``; ``noise``: its
    ``NoiseProfile`` ``(S, O)`` (:func:`noise_profile`)."""
    from pidng.core import RAW2DNG
    from pidng.defs import (
        CalibrationIlluminant,
        CFAPattern,
        DNGVersion,
        PhotometricInterpretation,
    )
    from pidng.dng import DNGTags, Tag

    linear = pattern is None
    if image.ndim != (3 if linear else 2) or (linear and image.shape[2] != 3):
        want = "(H, W, 3) RGB for a linear DNG" if linear else f"(H, W) mosaic for CFA {pattern}"
        raise ValueError(f"DNG image of shape {image.shape}: expected {want}")
    h, w = image.shape[:2]
    layout = ((Tag.SamplesPerPixel, 3), (Tag.BitsPerSample, [16, 16, 16]), (Tag.PlanarConfiguration, 1),
              (Tag.PhotometricInterpretation, PhotometricInterpretation.Linear_Raw)) if linear else (
              (Tag.SamplesPerPixel, 1), (Tag.BitsPerSample, 16),
              (Tag.PhotometricInterpretation, PhotometricInterpretation.Color_Filter_Array),
              (Tag.CFARepeatPatternDim, [2, 2]), (Tag.CFAPattern, getattr(CFAPattern, pattern.upper())))
    t = DNGTags()
    for tag, value in ((Tag.ImageWidth, w), (Tag.ImageLength, h), (Tag.TileWidth, w), (Tag.TileLength, h),
                       (Tag.Orientation, 1), *layout,
                       (Tag.BlackLevel, int(black)), (Tag.WhiteLevel, int(white)),
                       (Tag.ColorMatrix1, _rationals(matrix)),
                       (Tag.CalibrationIlluminant1, CalibrationIlluminant.D65),
                       (Tag.AsShotNeutral, _rationals(neutral)), (Tag.BaselineExposure, [[0, 1]]),
                       (Tag.Make, "illumix"), (Tag.Model, model), (Tag.UniqueCameraModel, f"illumix {model}"),
                       (Tag.DNGVersion, DNGVersion.V1_4), (Tag.DNGBackwardVersion, DNGVersion.V1_2)):
        t.set(tag, value)
    if description:
        t.set(Tag.ImageDescription, description)
    if noise is not None:
        t.set(Tag.NoiseProfile, [float(noise[0]), float(noise[1])])
    writer = RAW2DNG()
    writer.options(t, path="", compress=False)
    return bytes(writer.convert(np.ascontiguousarray(image, dtype=np.uint16)))


def template_bytes(*, black: int, white: int, pattern: str | None, matrix: np.ndarray, model: str,
                   noise: tuple[float, float] | None = None) -> bytes:
    """LSMI's per-camera template DNG (``<camera>.dng``: its scripts read ``black_level_per_channel``,
    ``white_level`` and ``raw_pattern`` from it): a 32 × 32 frame at the black level (libraw refuses
    frames under 22 pixels), a mosaic with ``pattern`` or linear without."""
    shape = (32, 32) if pattern else (32, 32, 3)
    return dng_bytes(np.full(shape, black, np.uint16), black=black, white=white, pattern=pattern, matrix=matrix,
                     neutral=[1.0, 1.0, 1.0], model=model, description="illumix export: camera template (levels)",
                     noise=noise)


def write_dng(path: Path, image: np.ndarray, **kw) -> None:
    Path(path).write_bytes(dng_bytes(image, **kw))


def dng_levels(noise: NoiseModel | None) -> tuple[int, int]:
    """``(black, white)`` the DNG states: the noise model's, else :data:`DNG_LEVELS`'s; whole numbers."""
    model = noise or DNG_LEVELS
    black, white = float(model.black_level), float(model.white)
    if not (black.is_integer() and white.is_integer()):
        raise SpectralError(f"format=dng states whole black and white levels; noise= gives {black:g} and {white:g}: "
                            "give noise=black_level:<integer>;white_level:<integer>")
    return int(black), int(white)
