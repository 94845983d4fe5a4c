"""Sensor model: photon shot noise + read noise, black level, white level, bit depth, Bayer CFA.

Input is noise-free linear raw ``(H, W, 3)`` scaled so 1.0 is the full-well (saturation) level
(apply exposure first). With full-well capacity ``FW`` electrons::

    e   ~ Poisson(FW · raw) + Normal(0, σ_read)                    electrons
    DN  = round(black + e / FW · (white − black)),  clipped to [0, white]  (white ≤ 2^bits − 1)

Ground truth is computed from the noise-free signal; this model only changes the raw a camera
would record. Generators are seeded (``numpy.random.default_rng(seed)``), so a sample is
reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.registry import MethodRegistry

BAYER_PATTERNS: MethodRegistry[str] = MethodRegistry("Bayer pattern", {p: p for p in ("RGGB", "BGGR", "GRBG", "GBRG")})

# Physical ranges. A full well beyond 1e9 e- or a read noise beyond 1e6 e- is no camera, and numpy's
# Poisson sampler refuses means near 1e19: refuse early with the range instead of failing inside.
MAX_FULL_WELL = 1e9
MAX_READ_NOISE = 1e6


@dataclass(frozen=True)
class NoiseModel:
    """Sensor parameters. ``white_level`` defaults to ``2^bit_depth − 1``."""

    full_well: float = 10000.0       # electrons at saturation
    read_noise: float = 2.0          # electrons RMS
    black_level: float = 64.0        # DN
    white_level: float | None = None  # DN
    bit_depth: int = 12

    def __post_init__(self) -> None:
        for name in ("full_well", "read_noise", "black_level", "white_level"):
            v = getattr(self, name)
            if v is not None and not np.isfinite(v):
                raise SpectralError(f"noise model: {name} must be a finite number, got {v}")
        if not (0 < self.full_well <= MAX_FULL_WELL and 0 <= self.read_noise <= MAX_READ_NOISE
                and isinstance(self.bit_depth, int) and 1 <= self.bit_depth <= 16):
            raise SpectralError(f"noise model: need 0 < full_well <= {MAX_FULL_WELL:g} e-, 0 <= read_noise <= "
                                f"{MAX_READ_NOISE:g} e-, 1 <= bit_depth <= 16 (an integer); got {self}")
        if not 0 <= self.black_level < self.white:
            raise SpectralError(f"noise model: black level {self.black_level} must be below white "
                                f"level {self.white}")
        if self.white > 2 ** self.bit_depth - 1:
            raise SpectralError(f"noise model: white level {self.white:g} does not fit in "
                                f"{self.bit_depth} bits (max {2 ** self.bit_depth - 1})")

    @property
    def white(self) -> float:
        return float(self.white_level if self.white_level is not None else 2 ** self.bit_depth - 1)


# Presets by name (case-insensitive): a clean base-ISO sensor, a typical phone sensor, and a
# high-ISO phone sensor.
NOISE_PRESETS: MethodRegistry[NoiseModel] = MethodRegistry("noise preset", {
    "low": NoiseModel(full_well=20000, read_noise=1.5, black_level=256, bit_depth=14),
    "phone": NoiseModel(full_well=6000, read_noise=2.5, black_level=64, bit_depth=12),
    "high": NoiseModel(full_well=1000, read_noise=4.0, black_level=64, bit_depth=10),
}, aliases={"base iso": "low", "high iso": "high"})


def simulate_raw(raw: np.ndarray, model: NoiseModel, seed: int | None = 0, *, noise: bool = True
                 ) -> np.ndarray:
    """Digital numbers ``(H, W, 3)`` float32 (integers stored as float) from normalised raw."""
    x = np.clip(np.nan_to_num(np.asarray(raw, dtype=np.float64)), 0.0, None)
    electrons = x * model.full_well
    if noise:
        rng = np.random.default_rng(seed)
        # Poisson is exact for shot noise; cap its mean far above full well to keep it finite.
        electrons = rng.poisson(np.minimum(electrons, 64 * model.full_well)).astype(np.float64)
        electrons += rng.normal(0.0, model.read_noise, size=electrons.shape)
    dn = model.black_level + electrons / model.full_well * (model.white - model.black_level)
    # A saturated pixel reads the white level (full well), not the ADC's largest code.
    return np.clip(np.round(dn), 0, model.white).astype(np.float32)


def mosaic(rgb: np.ndarray, pattern: str = "RGGB") -> np.ndarray:
    """Bayer colour-filter-array sampling of ``(H, W, 3)`` → ``(H, W)``; pattern names the 2×2 tile
    read row by row (``RGGB``: R at (0, 0), G at (0, 1) and (1, 0), B at (1, 1))."""
    pattern = BAYER_PATTERNS.canonical(pattern)
    out = np.empty(rgb.shape[:2], dtype=rgb.dtype)
    for (dy, dx), ch in zip(((0, 0), (0, 1), (1, 0), (1, 1)), pattern):
        out[dy::2, dx::2] = rgb[dy::2, dx::2, "RGB".index(ch)]
    return out
