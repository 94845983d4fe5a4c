"""Illuminants drawn for a dataset: on the Planckian locus, or beyond it (``--pairs draw:extended``).

Real rooms are not lit by blackbodies alone. :class:`IlluminantSampling` (``sampling``):

- ``planckian`` — blackbodies (``blackbody:<K>``, 2500–4500 K for the artificial light of a pair)
  and CIE daylight (``daylight:<K>``, 5000–9000 K for its daylight);
- ``extended`` — besides those, **measured LEDs and fluorescents** (colour-science: the CIE 2018 LED
  series and FL1–FL12 / FL3.x in ``SDS_ILLUMINANTS``, and the measured lamps of
  ``SDS_LIGHT_SOURCES`` — phosphor and multi-chip LEDs, tri-phosphor and broadband tubes),
  **coloured shades and gels** (a CIE illuminant A, D50 or a blackbody times a smooth transmission:
  a Gaussian pass band 30–100 nm wide over a floor of 5–40 %, never opaque), **daylight split
  into sky and sun** (skylight ``daylight:`` 9000–20000 K alone — a window in shade —, or direct sun
  (4500–5800 K) mixed with 10–50 % sky) and daylight through a coloured curtain (a paler filter).
  Measured lamps hug the locus (|Duv| ≤ 0.005 for 3 in 4 of them): the draws that leave it are mostly
  the filtered ones (the test measures at least 10 % of draws beyond |Duv| 0.01).

A pair is drawn as one daylight-kind and one artificial illuminant, so that ``pair=`` lights a
view's daylight groups with the first (:mod:`engine.lighting`); its colour temperature decides the
kind the engine sees (above 4500 K: daylight), and a draw whose kind comes out otherwise is drawn again.
Every drawn SPD passes the engine's upload gate (:func:`engine.library.parse_illuminant`:
:mod:`retarget.conditioning` through the reference sensors); the export then checks each against its
own sensors when it composes. Draws are a function of the seed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

FINE = np.arange(380.0, 781.0, 5.0)  # nm: the samples a drawn SPD is written with (CSV wavelength,value)
SAMPLINGS = ("planckian", "extended")
#: Probability of each family in ``extended`` sampling, for the artificial and the daylight light of a pair.
ARTIFICIAL_MIX = {"planckian": 0.2, "led": 0.25, "fluorescent": 0.25, "gel": 0.3}
DAYLIGHT_MIX = {"planckian": 0.25, "sky": 0.3, "sun": 0.3, "curtain": 0.15}


class IlluminantSampling(BaseModel):
    """How a dataset draws its illuminants (module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    sampling: Literal["planckian", "extended"] = Field("planckian", description="planckian: blackbodies and CIE "
                                                       "daylight; extended: also measured LEDs, fluorescents, gels "
                                                       "and daylight split into sky and sun")


@dataclass(frozen=True)
class Drawn:
    """A drawn illuminant: ``name`` (a built-in name the engine knows, or a file stem), ``family``,
    ``samples`` ``(len(FINE),)`` the SPD on :data:`FINE` (``None`` for a built-in name)."""

    name: str
    family: str
    samples: np.ndarray | None = None

    @property
    def builtin(self) -> bool:
        return self.samples is None

    def csv(self) -> bytes:
        """``wavelength,value`` rows of a drawn SPD (what ``--pairs`` and uploads read)."""
        rows = "\n".join(f"{w:g},{v:.8g}" for w, v in zip(FINE, self.samples))
        return f"wavelength,value\n{rows}\n".encode()


def _sd(name: str) -> np.ndarray:
    import colour

    sd = colour.SDS_ILLUMINANTS[name] if name in colour.SDS_ILLUMINANTS else colour.SDS_LIGHT_SOURCES[name]
    return np.asarray(sd.copy().align(colour.SpectralShape(380, 780, 5)).values, np.float64)


def measured(family: str) -> list[str]:
    """colour-science's measured lamps of ``family`` (``led`` or ``fluorescent``), sorted."""
    import colour

    names = list(colour.SDS_ILLUMINANTS) + list(colour.SDS_LIGHT_SOURCES)
    if family == "led":
        pick = [n for n in names if "LED" in n or n.startswith("PHOS")]
    else:
        pick = [n for n in names if re.match(r"^FL\d", n) or " FL" in n or "(Triphosphor)" in n or "Broadband FL" in n]
    return sorted(dict.fromkeys(pick))


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "-", text).strip("-.")


def _kelvin(rng: np.random.Generator, lo: float, hi: float) -> int:
    return int(round(rng.uniform(lo, hi) / 50.0) * 50)  # 50 K steps: the engine's caches stay warm


def _daylight_spd(kelvin: int) -> np.ndarray:
    import colour

    xy = colour.temperature.CCT_to_xy_CIE_D(kelvin * 1.4388 / 1.4380)
    return np.asarray(colour.sd_CIE_illuminant_D_series(xy).align(colour.SpectralShape(380, 780, 5)).values)


def _transmission(mu: float, sigma: float, floor: float) -> np.ndarray:
    """A smooth filter on :data:`FINE`: a Gaussian pass band (centre ``mu``, width ``sigma`` nm) over
    ``floor`` (never opaque: every channel keeps some light)."""
    return floor + (1 - floor) * np.exp(-0.5 * ((FINE - mu) / sigma) ** 2)


def _draw_family(rng: np.random.Generator, family: str) -> Drawn:
    """One illuminant of ``family`` (module docstring)."""
    import colour

    if family == "planckian":
        return Drawn(f"blackbody:{_kelvin(rng, 2500, 4500)}", family)
    if family == "daylight":
        return Drawn(f"daylight:{_kelvin(rng, 5000, 9000)}", family)
    if family in ("led", "fluorescent"):
        names = measured(family)
        name = names[int(rng.integers(len(names)))]
        return Drawn(name, family) if name in colour.SDS_ILLUMINANTS else Drawn(_slug(name), family, _sd(name))
    if family == "gel":
        base = ["A", "D50", f"blackbody:{_kelvin(rng, 2700, 4000)}"][int(rng.integers(3))]
        spd = (np.asarray(colour.sd_blackbody(float(base.split(":")[1]), colour.SpectralShape(380, 780, 5)).values)
               if base.startswith("blackbody") else _sd(base))
        mu, sigma, floor = rng.uniform(420, 680), rng.uniform(30, 100), rng.uniform(0.05, 0.4)
        return Drawn(f"gel-{_slug(base)}-{mu:.0f}nm-{sigma:.0f}-{floor:.2f}", family,
                     spd * _transmission(mu, sigma, floor))
    if family == "curtain":  # daylight through a coloured curtain or tinted glass: a paler filter
        k = _kelvin(rng, 5000, 12000)
        mu, sigma, floor = rng.uniform(420, 680), rng.uniform(50, 120), rng.uniform(0.2, 0.5)
        return Drawn(f"curtain-{k}K-{mu:.0f}nm-{sigma:.0f}-{floor:.2f}", family,
                     _daylight_spd(k) * _transmission(mu, sigma, floor))
    if family == "sky":
        k = _kelvin(rng, 9000, 20000)
        return Drawn(f"sky-{k}K", family, _daylight_spd(k))
    k, sky_k, f = _kelvin(rng, 4500, 5800), _kelvin(rng, 9000, 20000), rng.uniform(0.1, 0.5)  # sun + some sky
    sun, sky = _daylight_spd(k), _daylight_spd(sky_k)
    spd = (1 - f) * sun / sun.max() + f * sky / sky.max()
    return Drawn(f"sun-{k}K-sky-{sky_k}K-{f:.2f}", family, spd)


def _kind(d: Drawn, grid) -> str | None:
    """The kind the engine will see (:func:`engine.lighting.illuminant_kind`)."""
    from illumix.engine.lighting import illuminant_kind
    from illumix.retarget.illuminants import illuminant_spd, spd_from_samples

    if d.builtin:
        return illuminant_kind(d.name, lambda n: illuminant_spd(n, grid), grid)
    return illuminant_kind("drawn", lambda _: spd_from_samples(FINE, d.samples, grid), grid)


def conditioned(d: Drawn, grid) -> bool:
    """Whether ``d`` passes the engine's gate for an uploaded illuminant (module docstring)."""
    from illumix.engine.library import parse_illuminant
    from illumix.retarget.errors import SpectralError

    if d.builtin:
        return True  # built-ins are within the bounds with >= 10x margin (retarget.conditioning)
    try:
        parse_illuminant(d.name, d.csv(), grid, conditioned=True)
    except SpectralError:
        return False
    return True


def draw_one(rng: np.random.Generator, kind: str, sampling: str, grid, tries: int = 50) -> Drawn:
    """A ``kind`` (``daylight``/``artificial``) illuminant of ``sampling``, conditioned (module docstring)."""
    mix = DAYLIGHT_MIX if kind == "daylight" else ARTIFICIAL_MIX
    for _ in range(tries):
        if sampling == "planckian":
            family = "daylight" if kind == "daylight" else "planckian"
        else:
            family = list(mix)[int(rng.choice(len(mix), p=np.array(list(mix.values())) / sum(mix.values())))]
            family = "daylight" if (kind, family) == ("daylight", "planckian") else family
        d = _draw_family(rng, family)
        if _kind(d, grid) == kind and conditioned(d, grid):
            return d
    raise ValueError(f"no {kind} illuminant of {sampling} sampling passed the checks in {tries} draws")


def draw_pair(seed: int, sampling: str, grid) -> tuple[Drawn, Drawn]:
    """``(daylight, artificial)`` illuminants for one place, a function of ``seed``."""
    rng = np.random.default_rng(seed)
    return draw_one(rng, "daylight", sampling, grid), draw_one(rng, "artificial", sampling, grid)
