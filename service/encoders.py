"""The answer encodings of ``GET /sample`` and ``POST /batch``: one registry, keyed by ``format=``.

Each :class:`Encoder` says what the engine must compose for it (:meth:`Encoder.compose_spec`), what it
refuses once the request is planned (:meth:`Encoder.check`), the memory it needs beyond the engine's
price (:meth:`Encoder.extra_bytes`) and how it writes the answer (:meth:`Encoder.encode`; for the
formats a batch may use, :meth:`Encoder.encode_batch`). A new format is one class and one entry in
:data:`ENCODERS` (and its name in :data:`engine.spec.FORMATS`, which validates the request).
"""

from __future__ import annotations

import numpy as np

from illumix.engine.spec import FORMATS, SampleSpec
from illumix.service import arrays_format
from illumix.service import file_downloads as files
from illumix.service.encoding import MEDIA, encode_image, encode_npz, half_precision, image_output, meta_json, png_scale


class Encoder:
    """An answer format (module docstring). The defaults: compose the spec as asked, refuse nothing,
    need no extra memory, no batches."""

    name = ""
    batch = False  # usable by POST /batch

    @property
    def media_type(self) -> str:
        return MEDIA[self.name]

    def compose_spec(self, spec: SampleSpec) -> SampleSpec:
        return spec

    def check(self, p) -> None:
        """Refusals that need the plan (raise :class:`retarget.errors.SpectralError`)."""

    def extra_bytes(self, p) -> int:
        return 0

    def encode(self, p, ctx, arrays: dict[str, np.ndarray], meta: dict) -> tuple[object, dict[str, str]]:
        """``(body, headers)``: bytes, a memoryview or an :class:`service.arrays_format.Encoded`."""
        raise NotImplementedError

    def encode_batch(self, items: list[tuple[dict[str, np.ndarray], dict[str, float], dict | None]]) -> object:
        """One body for ``[(arrays, scales, meta or None)]`` (arrays already at their wire dtype)."""
        raise NotImplementedError


def wire_arrays(spec: SampleSpec, arrays: dict[str, np.ndarray], meta: dict) -> tuple[dict[str, np.ndarray], dict]:
    """``(arrays to send, scales)``: float16 with their scales (also put in ``meta["encoding"]``) when
    ``dtype=float16``, else as composed."""
    if spec.dtype != "float16":
        return arrays, {}
    arrays, scales = half_precision(arrays)
    meta["encoding"] = {"dtype": "float16", "scales": scales, "value": "stored * scale"}
    return arrays, scales


class Npz(Encoder):
    """``np.savez``: one array per output, ``meta`` as a JSON string (``{i}/…`` keys in a batch)."""

    name, batch = "npz", True

    def encode(self, p, ctx, arrays, meta):
        arrays, scales = wire_arrays(p.spec, arrays, meta)
        return encode_npz(arrays, meta if "meta" in p.spec.outputs else None, scales), {}

    def encode_batch(self, items):
        out: dict[str, np.ndarray] = {}
        for i, (arrays, scales, meta) in enumerate(items):
            out.update({f"{i}/{k}": v for k, v in arrays.items()})
            if meta is not None:
                out[f"{i}/meta"] = np.array(meta_json(meta))
            if scales:
                out[f"{i}/scales"] = np.array(meta_json(scales))
        return encode_npz(out, None)


class Arrays(Encoder):
    """The ``application/x-illumix-arrays`` container (:mod:`service.arrays_format`): arrays sent as
    views of the outputs themselves, the metadata in its header."""

    name, batch = "arrays", True

    def encode(self, p, ctx, arrays, meta):
        arrays, scales = wire_arrays(p.spec, arrays, meta)
        return arrays_format.encode(arrays, scales, **({"meta": meta} if "meta" in p.spec.outputs else {})), {}

    def encode_batch(self, items):
        arrays: dict[str, np.ndarray] = {}
        scales: dict[str, float] = {}
        for i, (a, s, _meta) in enumerate(items):
            arrays.update({f"{i}/{k}": v for k, v in a.items()})
            scales.update({f"{i}/{k}": v for k, v in s.items()})
        return arrays_format.encode(arrays, scales, items=[{"meta": m} if m is not None else {} for *_, m in items])


class Image(Encoder):
    """One 16-bit PNG or float32 TIFF of a single output (:func:`service.encoding.encode_image`)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def encode(self, p, ctx, arrays, meta):
        name = image_output(arrays, self.name)
        noise = p.noise if name == "raw" else None
        meta["encoding"] = png_scale(name, noise) if self.name == "png" else None
        body, headers = encode_image(arrays, self.name, noise=noise, meta=meta)
        headers["X-Illumix-Meta"] = meta_json({k: meta[k] for k in ("scene", "view", "seed", "size", "exposure_gain")})
        return body, headers


class Dng(Encoder):
    """A Bayer (or LinearRaw) DNG of the raw (:mod:`service.file_downloads`)."""

    name = "dng"

    def compose_spec(self, spec):
        return files.compose_spec(spec)

    def check(self, p):
        files.check(p)

    def encode(self, p, ctx, arrays, meta):
        return files.encode(p, ctx, arrays, meta, with_meta="meta" in p.spec.outputs)


class Exr(Dng):
    """Every output in one layered float32 OpenEXR (:mod:`service.file_downloads`)."""

    name = "exr"

    def extra_bytes(self, p):
        return files.extra_bytes(p)


ENCODERS: dict[str, Encoder] = {e.name: e for e in (Npz(), Arrays(), Image("png"), Image("tiff"), Dng(), Exr())}
if set(ENCODERS) != set(FORMATS):  # pragma: no cover - a format added to one and not the other
    raise RuntimeError(f"format= accepts {FORMATS}, the encoders are {sorted(ENCODERS)}")


def encoder(fmt: str) -> Encoder:
    """The encoder of ``format=`` (validated by :class:`engine.spec.SampleSpec`)."""
    return ENCODERS[fmt]


__all__ = ["ENCODERS", "Encoder", "encoder", "wire_arrays"]
