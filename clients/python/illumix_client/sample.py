"""The :class:`Sample` a request returns, request-parameter encoding and npz decoding.

Shared by :class:`illumix_client.Client` and :class:`illumix_client.AsyncClient`; no I/O here.
"""

from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from illumix_client.errors import IllumixError

OUTPUTS = ("raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture", "albedo", "normal", "depth",
           "reflectance", "illumination")
"""Array outputs the service can return (plus ``meta``)."""

SPEC_KEYS = ("scene", "view", "seed", "sensor", "pair", "illuminants", "intensities", "crop", "size",
             "outputs", "gt", "denoise", "exposure", "noise", "bayer")
"""Parameters of one sample request (GET /sample query parameters, POST /batch items)."""


@dataclass
class Sample:
    """One sample. Arrays are numpy, channels last, ``None`` when the output was not requested.

    - ``raw``: ``(H, W, 3)`` float32 linear camera RGB (``(H, W)`` when Bayer mosaicked). Relative
      units (unit-luminance illuminants × transport) unless ``exposure`` was set (then 1.0 = white
      level) or ``noise`` was set (then digital numbers, black level included).
    - ``gain``: ``(H, W, 3)`` float32 white-balance gain map, ``max_j W_j / W_k`` (≥ 1, G ≈ 1).
    - ``ccm``: ``(H, W, 3, 3)`` float32 per-pixel colour-correction matrix, white-balanced camera RGB
      → linear sRGB (``out = ccm @ rgb``).
    - ``srgb``: ``(H, W, 3)`` float32 rendered sRGB in [0, 1].
    - ``weights``: ``(H, W, G)`` float32 illuminant weights per light group, in ``meta["groups"]``
      order; they sum to 1 where ``mask`` is True.
    - ``mask``: ``(H, W)`` bool, True where the ground truth is defined (a lit surface; not sky, not a
      light source's own surface); ``meta["mask_reasons"]`` counts the others by reason.
    - ``illum``: ``(H, W, 3)`` float32 per-pixel white point in camera RGB, G = 1 (LSMI's
      illumination map) — physical (bounce light included) where the store has illumination cubes,
      else the formula's; ``meta["ground_truth"]`` says which.
    - ``mixture``: ``(H, W, G)`` float32 each light group's share of that white point (≥ 0, sum 1).
    - ``albedo`` / ``normal`` ``(H, W, 3)``, ``depth`` ``(H, W)``: the view's geometry AOVs.
    - ``reflectance`` / ``illumination``: ``(H, W, bands)`` float32 per-pixel spectra (the first hit's
      reflectance; the radiance a white Lambertian surface there sends under this lighting).
    - ``meta``: the service's metadata (scene, view, groups, illuminants with sensor white points and
      CCMs, intensities, exposure gain, seed, ground truth, provenance, timings); ``{}`` when not
      requested.
    """

    raw: np.ndarray | None = None
    gain: np.ndarray | None = None
    ccm: np.ndarray | None = None
    srgb: np.ndarray | None = None
    weights: np.ndarray | None = None
    mask: np.ndarray | None = None
    illum: np.ndarray | None = None
    mixture: np.ndarray | None = None
    albedo: np.ndarray | None = None
    normal: np.ndarray | None = None
    depth: np.ndarray | None = None
    reflectance: np.ndarray | None = None
    illumination: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    @property
    def scene(self) -> str | None:
        return self.meta.get("scene")

    @property
    def view(self) -> str | None:
        return self.meta.get("view")

    @property
    def seed(self) -> int | None:
        return self.meta.get("seed")

    def arrays(self) -> dict[str, np.ndarray]:
        """The outputs that are present, by name."""
        return {k: getattr(self, k) for k in OUTPUTS if getattr(self, k) is not None}


def _join(value: Any, what: str) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, Iterable):
        return ",".join(_scalar(v, what) for v in value)
    raise TypeError(f"{what}: expected a string or a sequence, got {type(value).__name__}")


def _scalar(v: Any, what: str) -> str:
    if isinstance(v, (bool, np.bool_)):
        raise TypeError(f"{what}: booleans are not allowed")
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return v
    raise TypeError(f"{what}: cannot encode {v!r}")


def encode_spec(spec: Mapping[str, Any]) -> dict[str, Any]:
    """Sample parameters → the service's wire form (strings, ``seed`` an int), ``None`` dropped.

    Accepts Python shapes: ``pair``/``illuminants``/``outputs`` a sequence of names or a
    comma-separated string; ``intensities`` a sequence of numbers; ``crop`` ``(x, y, w, h)`` pixels;
    ``size`` ``(W, H)`` pixels or ``"WxH"``; ``exposure`` ``"auto"``, ``"adaptive"`` or a number;
    ``noise`` a preset name or a mapping ``{"full_well": 8000, "read_noise": 3, ...}``. The result
    works both as GET query parameters and as a POST /batch JSON item.
    """
    unknown = set(spec) - set(SPEC_KEYS)
    if "format" in unknown:
        raise ValueError("sample()/batch() return npz arrays; use Client.image() for png/tiff")
    if unknown:
        raise TypeError(f"unknown sample parameter(s) {sorted(unknown)}; known: {', '.join(SPEC_KEYS)}")
    out: dict[str, Any] = {}
    for key, value in spec.items():
        if value is None:
            continue
        if key == "seed":
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise TypeError(f"seed must be a non-negative int, got {value!r}")
            out[key] = int(value)
        elif key in ("pair", "illuminants", "outputs", "intensities", "crop"):
            out[key] = _join(value, key)
        elif key == "size":
            if isinstance(value, str):
                out[key] = value
            else:
                w, h = value
                out[key] = f"{int(w)}x{int(h)}"
        elif key == "noise" and isinstance(value, Mapping):
            out[key] = ";".join(f"{k}:{_scalar(v, 'noise')}" for k, v in value.items())
        else:
            out[key] = _scalar(value, key)
    return out


def _open_npz(content: bytes):
    try:
        return np.load(io.BytesIO(content), allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile) as exc:
        raise IllumixError(f"the response is not a valid npz archive ({exc})") from None


def _meta(arr: np.ndarray) -> dict:
    try:
        return json.loads(str(arr[()]))
    except ValueError as exc:
        raise IllumixError(f"the response's meta is not valid JSON ({exc})") from None


def _sample(arrays: Mapping[str, np.ndarray]) -> Sample:
    s = Sample()
    for k, v in arrays.items():
        if k == "meta":
            s.meta = _meta(v)
        elif k in OUTPUTS:
            setattr(s, k, v)
    return s


def parse_sample(content: bytes) -> Sample:
    """Decode a GET /sample npz response."""
    with _open_npz(content) as z:
        return _sample({k: z[k] for k in z.files})


def parse_batch(content: bytes, n: int) -> list[Sample]:
    """Decode a POST /batch npz response (keys ``"{i}/{output}"``) into ``n`` samples, in order."""
    per: list[dict[str, np.ndarray]] = [{} for _ in range(n)]
    with _open_npz(content) as z:
        for key in z.files:
            i, sep, name = key.partition("/")
            if not sep or not i.isdigit() or int(i) >= n:
                raise IllumixError(f"unexpected key {key!r} in a batch of {n}")
            per[int(i)][name] = z[key]
    return [_sample(a) for a in per]


def as_specs(specs: Sequence[Mapping[str, Any]] | Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Encode a batch of sample specs (each a mapping of :data:`SPEC_KEYS`)."""
    out = [encode_spec(s) for s in specs]
    if not out:
        raise ValueError("batch() needs at least one sample spec")
    return out
