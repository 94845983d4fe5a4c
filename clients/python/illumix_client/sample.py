"""The :class:`Sample` a request returns, request-parameter encoding and response decoding (npz or
the arrays container, told apart by their first bytes; float16 outputs scaled back).

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

from illumix_client import arrays_format
from illumix_client.errors import IllumixError

OUTPUTS = ("raw", "gain", "ccm", "srgb", "weights", "mask", "illum", "mixture", "albedo", "normal", "depth",
           "reflectance", "illumination")
"""Array outputs the service can return (plus ``meta``)."""

SPEC_KEYS = ("scene", "view", "seed", "sensor", "pair", "illuminants", "intensities", "crop", "size",
             "outputs", "gt", "denoise", "exposure", "noise", "bayer", "dtype")
"""Parameters of one sample request (GET /sample query parameters, POST /batch items)."""


@dataclass
class Sample:
    """One sample. Arrays are numpy, channels last, ``None`` when the output was not requested.

    - ``raw``: ``(H, W, 3)`` float32 linear camera RGB (``(H, W)`` when Bayer mosaicked). Relative
      units (unit-luminance illuminants × transport) unless ``exposure`` was set (then 1.0 = white
      level) or ``noise`` was set (then digital numbers, black level included).
    - ``gain``: ``(H, W, 3)`` float32 white-balance gain map, ``max_j W_j / W_k`` (≥ 1, G ≈ 1).
    - ``ccm``: ``(H, W, 3, 3)`` float32 per-pixel colour-correction matrix, white-balanced camera RGB
      → linear sRGB (``out = ccm @ rgb``); sent only when requested — :meth:`ccm_map` rebuilds it.
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
    - ``scales``: ``{output: scale}`` of float16 outputs kept as sent (``dtype="float16"`` with
      ``Client(keep_float16=True)``): value = ``stored.astype(np.float32) * scale``; ``{}`` otherwise
      (float16 outputs are then scaled back to float32 on arrival).

    ``ccm`` is not sent by default; :meth:`ccm_map` rebuilds it from ``mixture`` (or ``weights``)
    and the per-group CCMs in ``meta``.
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
    scales: dict = field(default_factory=dict)

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

    def value(self, name: str) -> np.ndarray | None:
        """Output ``name``'s values: a float16 output kept as sent (``keep_float16=True``) as float32
        ``stored × scale``; any other output as it is; ``None`` when absent."""
        a = getattr(self, name)
        if a is None or name not in self.scales:
            return a
        return np.multiply(a, np.float32(self.scales[name]), dtype=np.float32)

    def ccm_map(self) -> np.ndarray:
        """``(H, W, 3, 3)`` float32 per-pixel CCM, ``CCM(x) = Σ_g m_g(x) CCM_g``, computed as the
        service computes its ``ccm`` output: ``m`` is ``mixture`` (either ground truth; for the
        formula it equals ``weights``, which serves too) and ``CCM_g`` is
        ``meta["illuminants"][g]["ccm"]``. Needs ``meta`` and ``mixture`` (or, with
        ``meta["ground_truth"]["method"] == "formula"``, ``weights``) among the outputs."""
        if self.ccm is not None:
            return self.value("ccm")
        if not self.meta.get("illuminants"):
            raise ValueError("ccm_map() needs the sample's meta: request outputs including 'meta'")
        method = self.meta.get("ground_truth", {}).get("method")
        name = "mixture" if self.mixture is not None else ("weights" if method == "formula" else None)
        if name is None or getattr(self, name) is None:
            raise ValueError(f"ccm_map() needs the 'mixture' output{' (or weights)' if method == 'formula' else ''}"
                             " with this sample's ground truth: request outputs including 'mixture' and 'meta'")
        m = self.value(name)
        ccms = np.asarray([i["ccm"] for i in self.meta["illuminants"]], dtype=np.float32).reshape(-1, 9)
        if ccms.shape[0] != m.shape[-1]:
            raise ValueError(f"{name} has {m.shape[-1]} groups but meta lists {ccms.shape[0]} CCMs")
        if not isinstance(m, np.ndarray):  # a torch tensor (the local mode's device=): the product stays there
            import torch

            return (m.float() @ torch.as_tensor(ccms, device=m.device)).reshape(*m.shape[:-1], 3, 3)
        return (m.astype(np.float32, copy=False) @ ccms).reshape(*m.shape[:-1], 3, 3)


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
        raise ValueError("sample()/batch() return arrays (choose the wire format with Client(wire_format='npz'|"
                         "'arrays')); use Client.image() for png/tiff")
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


def _open_npz(content: bytes | bytearray):
    try:
        return np.load(io.BytesIO(content), allow_pickle=False)
    except (ValueError, OSError, zipfile.BadZipFile) as exc:
        raise IllumixError(f"the response is not a valid npz archive ({exc})") from None


def _json(arr: np.ndarray | str, what: str = "meta") -> dict:
    try:
        return json.loads(str(arr[()]) if isinstance(arr, np.ndarray) else arr)
    except ValueError as exc:
        raise IllumixError(f"the response's {what} is not valid JSON ({exc})") from None


def _sample(arrays: Mapping[str, np.ndarray], meta: dict | None, scales: Mapping[str, float],
            keep_float16: bool) -> Sample:
    """A :class:`Sample` of decoded outputs; float16 outputs with a scale become float32 values
    (``stored × scale``) unless ``keep_float16``."""
    s = Sample(meta=meta or {})
    for k, v in arrays.items():
        if k not in OUTPUTS:
            continue
        if k in scales:
            if keep_float16:
                s.scales[k] = float(scales[k])
            else:
                v = np.multiply(v, np.float32(scales[k]), dtype=np.float32)
        setattr(s, k, v)
    return s


def _npz_items(content) -> dict[str, np.ndarray]:
    with _open_npz(content) as z:
        return {k: z[k] for k in z.files}


def _split(key: str, n: int) -> tuple[int, str]:
    i, sep, name = key.partition("/")
    if not sep or not i.isdigit() or int(i) >= n:
        raise IllumixError(f"unexpected key {key!r} in a batch of {n}")
    return int(i), name


def parse_sample(content: bytes | bytearray, keep_float16: bool = False) -> Sample:
    """Decode a GET /sample answer (npz or arrays; see :mod:`illumix_client.arrays_format`)."""
    if content[:len(arrays_format.MAGIC)] == arrays_format.MAGIC:
        arrays, header = arrays_format.decode(content)
        return _sample(arrays, header.get("meta"), arrays_format.scales(header), keep_float16)
    z = _npz_items(content)
    meta = _json(z.pop("meta")) if "meta" in z else None
    scales = _json(z.pop("scales"), "scales") if "scales" in z else {}
    return _sample(z, meta, scales, keep_float16)


def parse_batch(content: bytes | bytearray, n: int, keep_float16: bool = False) -> list[Sample]:
    """Decode a POST /batch answer (npz keys ``"{i}/{output}"``, ``"{i}/meta"``, ``"{i}/scales"``; or
    arrays ``"{i}/{output}"`` with the metas in the header's ``items``) into ``n`` samples, in order."""
    per: list[dict[str, np.ndarray]] = [{} for _ in range(n)]
    metas: list[dict | None] = [None] * n
    scales: list[dict[str, float]] = [{} for _ in range(n)]
    if content[:len(arrays_format.MAGIC)] == arrays_format.MAGIC:
        arrays, header = arrays_format.decode(content)
        items = header.get("items", [])
        if not isinstance(items, list) or len(items) != n:
            raise IllumixError(f"the batch answer lists {len(items) if isinstance(items, list) else '?'} items, "
                               f"expected {n}")
        metas = [it.get("meta") if isinstance(it, dict) else None for it in items]
        for key, scale in arrays_format.scales(header).items():
            i, name = _split(key, n)
            scales[i][name] = scale
    else:
        arrays = _npz_items(content)
    for key, a in arrays.items():
        i, name = _split(key, n)
        if name == "meta":
            metas[i] = _json(a)
        elif name == "scales":
            scales[i] = _json(a, "scales")
        else:
            per[i][name] = a
    return [_sample(a, m, sc, keep_float16) for a, m, sc in zip(per, metas, scales)]


def as_specs(specs: Sequence[Mapping[str, Any]] | Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Encode a batch of sample specs (each a mapping of :data:`SPEC_KEYS`)."""
    out = [encode_spec(s) for s in specs]
    if not out:
        raise ValueError("batch() needs at least one sample spec")
    return out
