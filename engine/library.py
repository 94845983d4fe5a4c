"""Sensors and illuminants for the service: built-ins plus uploads persisted in the store registry,
with cached sensor objects and CCMs (the per-request work is then only the cubes).
"""

from __future__ import annotations

import hashlib
import threading
from dataclasses import replace
from functools import lru_cache

import numpy as np

from illumix.retarget import conditioning as cond
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.retarget.ccm import fit_ccm
from illumix.retarget.errors import SpectralError, unknown_name
from illumix.retarget.grid import SpectralGrid
from illumix.retarget.reflectances import DEFAULT_TRAINING_SET, get_reflectances
from illumix.retarget.tables import read_csv_table


class Library:
    """Name → sensor / illuminant resolution over built-ins and a store's upload registries.

    Uploaded names may not shadow built-in ones. Every derived quantity is cached under a key that
    includes the content hash of the upload, so an overwrite or delete can never serve stale data.
    """

    def __init__(self, store) -> None:
        self.store = store
        self._lock = threading.Lock()
        self._sensors: dict[tuple, sen.Sensor] = {}

    # -- registries -------------------------------------------------------------------------
    def _registry(self, kind: str):
        return self.store.registry(kind)

    def uploaded_sensors(self) -> list[str]:
        return sorted(self._registry("sensors").names())

    def uploaded_illuminants(self) -> list[str]:
        return sorted(self._registry("illuminants").names())

    def _upload(self, kind: str, name: str) -> tuple[bytes, str] | None:
        reg = self._registry(kind)
        return reg.get(name) if name in reg.names() else None

    # -- sensors ----------------------------------------------------------------------------
    def is_builtin_sensor(self, name: str) -> bool:
        return name in sen.builtin_names()

    def sensor(self, name: str, grid: SpectralGrid) -> tuple[sen.Sensor, str]:
        """``(Sensor, cache key)`` for a built-in or uploaded sensor name, or ``random:<seed>``: a
        camera drawn from the prior of the measured cameras in ``ILLUMIX_SENSOR_PATH``
        (:mod:`sensor_estimate.draw`; ``sensor=random`` names the request's seed)."""
        if name.lower().startswith(RANDOM + ":"):
            return random_sensor(name, grid), f"random:{name.partition(':')[2]}"
        if self.is_builtin_sensor(name):
            return sen.get_sensor(name, grid), f"builtin:{name}"
        up = self._upload("sensors", name)
        if up is None:
            raise unknown_name("sensor", name, sen.builtin_names() + self.uploaded_sensors())
        data, fmt = up
        key = ("sensor", name, hashlib.sha1(data).hexdigest(), grid)
        with self._lock:
            s = self._sensors.get(key)
        if s is None:
            s = parse_sensor(name, data, fmt, grid, conditioned=False)
            with self._lock:
                self._sensors[key] = s
        return s, f"upload:{name}:{key[2]}"

    def camera_noise(self, name: str):
        """``(NoiseModel, CFA pattern or None)`` a sensor file states (``noise=camera``): the DNG levels
        and ``NoiseProfile`` ``(S, O)`` it was estimated from, as full well ``1/S`` electrons and read
        noise ``√O/S`` electrons (variance ``S·x + O`` of a signal ``x`` in [0, 1]), and its mosaic."""
        data = None
        up = None if name.lower().startswith(RANDOM + ":") else self._upload("sensors", name)
        if up is not None:
            data = up[0]
        else:
            path = sen.sensor_file(name)
            data = path.read_bytes() if path is not None else None
        model = _sensor_model(data)
        if model is None:
            raise SpectralError(f"sensor {name!r} states no camera noise model; noise=camera needs a sensor "
                                "estimated from a DNG with a NoiseProfile (illumix sensors estimate --from-raw), "
                                "or give noise=low|phone|high|key:value")
        return model

    # -- illuminants ------------------------------------------------------------------------
    def illuminant(self, name: str, grid: SpectralGrid) -> tuple[np.ndarray, str]:
        """``(normalised SPD (n_bands,), cache key)``."""
        up = None
        if not ill.is_builtin(name) and ":" not in name:
            up = self._upload("illuminants", name)
        if up is None:
            if not ill.is_builtin(name) and name.partition(":")[0].lower() not in ill.PARAMETRIC:
                raise unknown_name("illuminant", name, ill.builtin_names()
                                   + [f"{k}:<K>" for k in ill.PARAMETRIC] + self.uploaded_illuminants())
            return ill.illuminant_spd(name, grid), f"builtin:{name}"
        data, _ = up
        return (parse_illuminant(name, data, grid, conditioned=False),
                f"upload:{name}:{hashlib.sha1(data).hexdigest()}")

    # -- derived, cached ----------------------------------------------------------------------
    def ccm(self, sensor: sen.Sensor, skey: str, spd: np.ndarray, ikey: str,
            illuminant: str | None = None) -> tuple[np.ndarray, cond.Conditioning]:
        """``(CCM (3, 3), its Conditioning)`` of a sensor × illuminant, fitted once per cache-key pair.

        Refuses (:class:`SpectralError`, one line) a pair beyond the bounds of
        :mod:`retarget.conditioning`, whoever asks: a degenerate CCM is never served, whatever the
        route. ``illuminant`` names it in that message (default: the name in its cache key)."""
        matrix, q = _ccm(skey, ikey, sensor.grid, _Frozen(sensor.weights()), _Frozen(spd))
        cond.require(q, sensor.name, illuminant or _display(ikey))
        return matrix, q


def _display(ikey: str) -> str:
    """The illuminant name in a cache key (``builtin:<name>`` or ``upload:<name>:<sha1>``)."""
    kind, _, rest = ikey.partition(":")
    return rest.rpartition(":")[0] if kind == "upload" else rest


class _Frozen:
    """Carries an array through lru_cache without hashing it (the string keys identify it)."""

    def __init__(self, a: np.ndarray) -> None:
        self.a = a

    def __hash__(self) -> int:
        return 0

    def __eq__(self, other: object) -> bool:
        return True


@lru_cache(maxsize=4096)
def _ccm(skey: str, ikey: str, grid: SpectralGrid, w: _Frozen, spd: _Frozen
         ) -> tuple[np.ndarray | None, cond.Conditioning]:
    """The fit and its conditioning; no fit (``None``) where the white point is already beyond its
    bound (a zero channel would make the fit refuse with a less telling message)."""
    rgb, gain = cond.white_gains(w.a, spd.a)
    white = cond.Conditioning(tuple(map(float, rgb[0])), float(gain[0]))
    if not gain[0] <= cond.MAX_WHITE_GAIN:
        return None, white
    _, refl = get_reflectances(DEFAULT_TRAINING_SET, grid)
    fit = fit_ccm(w.a, spd.a, refl, grid)
    return fit.matrix, replace(white, condition=fit.condition, delta_e00_mean=fit.delta_e00_mean,
                               delta_e00_max=fit.delta_e00_max)


def parse_sensor(name: str, data: bytes, fmt: str, grid: SpectralGrid, *, conditioned: bool = True) -> sen.Sensor:
    """Validate uploaded sensor bytes (rawtoaces JSON or CSV ``wavelength,r,g,b``) into a Sensor.

    ``conditioned`` (an upload): also refuse a sensor that is degenerate under the reference
    illuminants (:data:`retarget.conditioning.REFERENCE_ILLUMINANTS`), before it is stored. The
    library re-reads stored sensors with ``False``: each composition checks its own pair
    (:meth:`Library.ccm`), which also covers sensors stored before these bounds existed."""
    wl, rgb = sen.read_sensor_file(data, fmt=fmt, what=f"uploaded sensor {name!r}")
    s = sen.sensor_from_samples(name, wl, rgb, grid, source="uploaded")
    if conditioned:
        refs = cond.REFERENCE_ILLUMINANTS
        _check_reference(s.weights(), np.stack([ill.illuminant_spd(n, grid) for n in refs]), grid,
                         [name] * len(refs), list(refs), "sensor")
    return s


def parse_illuminant(name: str, data: bytes, grid: SpectralGrid, *, conditioned: bool = True) -> np.ndarray:
    """Validate uploaded SPD bytes (CSV ``wavelength,value``) into a normalised band-averaged SPD.

    ``conditioned`` (an upload): also refuse an SPD that is degenerate through the reference sensors
    (:data:`retarget.conditioning.REFERENCE_SENSORS`); see :func:`parse_sensor`."""
    wl, v, _ = read_csv_table(data, columns=1, what=f"uploaded illuminant {name!r}")
    spd = ill.spd_from_samples(wl, v[:, 0], grid, what=f"uploaded illuminant {name!r}")
    if conditioned:
        for s in cond.REFERENCE_SENSORS:
            _check_reference(sen.get_sensor(s, grid).weights(), spd[None], grid, [s], [name], "illuminant")
    return spd


def _check_reference(weights: np.ndarray, spds: np.ndarray, grid: SpectralGrid, sensors: list[str],
                     illuminants: list[str], blame: str) -> None:
    """Refuse (:mod:`retarget.conditioning`) the first degenerate pair of one sensor's ``(n_bands, 3)``
    weights × ``(G, n_bands)`` SPDs: all white points first (one product), then each CCM fit."""
    rgb, gains = cond.white_gains(weights, spds)
    for r, g, s, i in zip(rgb, gains, sensors, illuminants):
        cond.check_white(r, float(g), s, i, blame)
    _, refl = get_reflectances(DEFAULT_TRAINING_SET, grid)
    for spd, s, i in zip(spds, sensors, illuminants):
        cond.check_ccm(fit_ccm(weights, spd, refl, grid).condition, s, i, blame)


def check_upload_name(kind: str, name: str, builtin: list[str]) -> None:
    """Refuse an upload name a built-in already answers to: lookups ignore case, so ``d65`` would
    be stored and never served (the upload form's schema pattern states the same rule)."""
    taken = name.casefold() in {b.casefold() for b in builtin}
    if taken or (kind == "illuminants" and ":" in name):
        raise SpectralError(f"{kind[:-1]} name {name!r} is taken by a built-in (names are matched ignoring "
                            "case); choose another name")


RANDOM = "random"


def random_sensor(name: str, grid: SpectralGrid) -> sen.Sensor:
    """The camera ``random:<seed>`` names (module docstring of :mod:`sensor_estimate.draw`)."""
    from illumix.sensor_estimate.draw import draw_camera, measured_prior

    seed_text = name.partition(":")[2]
    if not seed_text.isdigit() or int(seed_text) >= 2**32:
        raise SpectralError(f"sensor {name!r}: random:<seed> takes a whole number 0..4294967295, e.g. random:7")
    folders = tuple(str(d) for d in sen.sensor_dirs())
    if not folders:
        raise SpectralError("sensor=random draws from measured cameras, and this service has none: start it "
                            "with ILLUMIX_SENSOR_PATH pointing at rawtoaces camera JSON files")
    curves = draw_camera(measured_prior(folders, grid), int(seed_text))
    return sen.Sensor(name=f"{RANDOM}:{int(seed_text)}", grid=grid, sensitivities=curves / curves.max(),
                      source=f"drawn from a prior of measured cameras ({', '.join(folders)})")


def _sensor_model(data: bytes | None):
    """``(NoiseModel, CFA pattern or None)`` of a camera JSON's ``header.illumix_estimate.sensor_model``,
    or None."""
    import json
    import math

    from illumix.retarget.sensor_model import BAYER_PATTERNS, MAX_FULL_WELL, MAX_READ_NOISE, NoiseModel

    if not data or data.lstrip()[:1] != b"{":
        return None
    try:
        m = json.loads(data)["header"]["illumix_estimate"]["sensor_model"]
        s_, o_ = (float(x) for x in m["noise_profile"])
        black, white = float(m["black_level"]), float(m["white_level"])
    except (KeyError, TypeError, ValueError):
        return None
    full_well = min(1.0 / s_, MAX_FULL_WELL)
    read = min(math.sqrt(o_) * full_well, MAX_READ_NOISE)
    bits = max(1, min(16, math.ceil(math.log2(white + 1))))
    cfa = m.get("bayer")
    cfa = cfa.upper() if isinstance(cfa, str) and cfa.upper() in BAYER_PATTERNS else None
    return NoiseModel(full_well=full_well, read_noise=read, black_level=black, white_level=white, bit_depth=bits), cfa
