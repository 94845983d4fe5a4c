"""The synchronous client (httpx). See :class:`Client`."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from time import sleep as _sleep  # a module global, so tests can patch the waits
from typing import Any

import httpx

from illumix_client import _protocol as P
from illumix_client.sample import Sample

DEFAULT_TIMEOUT = httpx.Timeout(60.0, connect=5.0)


class Client:
    """Talks to an illumix service over HTTP.

    ``Client("http://127.0.0.1:8000", token=None, timeout=60.0, retry=RetryPolicy())``. ``token`` is
    sent as ``Authorization: Bearer`` (needed for uploads and deletes when the service has one);
    ``timeout`` is seconds (or an ``httpx.Timeout``) per try; ``retry`` bounds the retries on
    connection errors, 5xx and 408 (never on other 4xx, see :mod:`illumix_client._protocol`);
    ``transport`` replaces httpx's network transport (tests pass an ``httpx.MockTransport``).
    ``wire_format`` is how :meth:`sample`/:meth:`batch` answers travel: ``"arrays"`` (the default;
    the flat container of :mod:`illumix_client.arrays_format`, decoded without copying the arrays)
    or ``"npz"``. With ``sample(dtype="float16")`` the float outputs travel as float16 with a
    power-of-two scale each; they are scaled back to float32 on arrival unless ``keep_float16=True``
    (then ``Sample.scales`` holds the scales: value = ``stored.astype(float32) * scale``).
    Errors are raised as :class:`illumix_client.IllumixError` subclasses. Thread-safe; use as a
    context manager or call :meth:`close`.
    """

    def __init__(self, base_url: str = "http://127.0.0.1:8000", token: str | None = None,
                 timeout: float | httpx.Timeout | None = DEFAULT_TIMEOUT,
                 retry: P.RetryPolicy | None = None, transport: httpx.BaseTransport | None = None,
                 wire_format: str = "arrays", keep_float16: bool = False) -> None:
        self.base_url = P.check_base_url(base_url)
        self.wire_format, self.keep_float16 = P.check_wire_format(wire_format), bool(keep_float16)
        self.retry = retry or P.RetryPolicy()
        self._http = httpx.Client(base_url=self.base_url, headers=P.headers(token), timeout=timeout,
                                  transport=transport)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._http.close()

    def _run(self, call: P.Call) -> Any:
        return P.run_sync(call, self.retry, self.base_url, self._send, _sleep)

    def _send(self, call: P.Call) -> httpx.Response:
        if not call.buffered:
            return self._http.request(call.method, call.path, **call.request_kwargs())
        request = self._http.build_request(call.method, call.path, **call.request_kwargs())
        return P.read_body(call, self._http.send(request, stream=True))

    # -- reads -----------------------------------------------------------------------------------
    def health(self) -> dict:
        """``{"status": "ok", "scenes": n, "cache_bytes": ..., ...}``."""
        return self._run(P.health())

    def scenes(self) -> list[dict]:
        """``[{"name", "views": [{"name", "width", "height", "groups": [{"name", "emission"}]}]}]``."""
        return self._run(P.scenes())

    def sensors(self) -> dict:
        """``{"builtin": [names], "uploaded": [names]}``."""
        return self._run(P.sensors())

    def sensor(self, name: str) -> dict:
        """One sensor: ``name``, ``source``, ``grid``, ``wavelengths`` ``(n,)`` nm and
        ``sensitivities`` ``(n, 3)`` (numpy)."""
        return self._run(P.sensor(name))

    def illuminants(self) -> dict:
        """``{"builtin": [usable names], "unavailable": {name: why}, "parametric": {"blackbody":
        {"min_kelvin", "max_kelvin"}, ...}, "uploaded": [names]}`` (``unavailable``: built-ins whose
        tables do not cover the service's spectral grid)."""
        return self._run(P.illuminants())

    def sample(self, scene: str | None = None, view: str | None = None, *, seed: int | None = None,
               sensor: str | None = None, pair: str | Sequence[str] | None = None,
               illuminants: str | Sequence[str] | None = None,
               intensities: str | Sequence[float] | None = None,
               crop: str | Sequence[int] | None = None, size: str | Sequence[int] | None = None,
               outputs: str | Sequence[str] | None = None, gt: str | None = None,
               denoise: str | None = None,
               exposure: str | float | None = None,
               noise: str | Mapping[str, float] | None = None, bayer: str | None = None,
               dtype: str | None = None) -> Sample:
        """One sample (GET /sample) as a :class:`Sample`.

        ``pair=("A", "D65")`` lights the view's first two groups; ``illuminants=[...]`` gives one per
        group; ``intensities`` one per lit group (default 1); ``crop=(x, y, w, h)`` and
        ``size=(W, H)`` in pixels; ``outputs`` a subset of raw, gain, ccm, srgb, weights, mask, illum,
        mixture, albedo, normal, depth, reflectance, illumination, meta (default: raw, gain, srgb,
        weights, mask, illum, mixture and meta — ``ccm`` only when asked for; ``Sample.ccm_map()``
        rebuilds it from mixture and meta); ``gt`` ``"physical"`` (bounce light included; the default where the store has
        illumination cubes) or ``"formula"`` (thesis eq. 3.3); ``denoise`` ``"none"`` or a method
        (``"dt-irradiance"``): the store's denoised cube copies (default: those where stored); ``exposure`` ``"auto"``/``"adaptive"``/a gain; ``noise`` a preset
        (low, phone, high) or a mapping of sensor parameters; ``bayer`` RGGB/BGGR/GRBG/GBRG;
        ``dtype`` ``"float32"`` (default) or ``"float16"`` (half the bytes on the wire; relative error
        ≤ 2^-11 down to 2^-28 of each output's maximum; see ``keep_float16``).
        ``scene``/``view`` omitted are drawn by the service, reproducibly given ``seed``.
        """
        return self._run(P.sample(_spec(locals()), self.wire_format, self.keep_float16))

    def batch(self, specs: Iterable[Mapping[str, Any]]) -> list[Sample]:
        """Many samples in one POST /batch; each spec is a mapping of :meth:`sample`'s parameters.
        Samples come back in the order of ``specs``."""
        return self._run(P.batch(specs, self.wire_format, self.keep_float16))

    def image(self, output: str = "srgb", format: str = "png", **spec: Any) -> bytes:
        """One output encoded as a PNG or TIFF file (bytes); ``spec`` as for :meth:`sample`."""
        return self._run(P.image(output, format, spec))

    # -- writes (need the token when the service has one) ---------------------------------------
    def upload_sensor(self, name: str, path: str | Path | bytes, overwrite: bool = False) -> dict:
        """Register a sensor from a rawtoaces camera JSON or a CSV ``wavelength,r,g,b`` (a path, or
        the file's bytes). Returns ``{"name", "format", "bytes"}``."""
        return self._run(P.upload("sensors", name, path, overwrite))

    def delete_sensor(self, name: str) -> dict:
        """Delete an uploaded sensor (built-ins raise :class:`ForbiddenError`)."""
        return self._run(P.delete("sensors", name))

    def upload_illuminant(self, name: str, path: str | Path | bytes, overwrite: bool = False) -> dict:
        """Register an illuminant from an SPD CSV ``wavelength,value`` (a path or bytes)."""
        return self._run(P.upload("illuminants", name, path, overwrite))

    def delete_illuminant(self, name: str) -> dict:
        """Delete an uploaded illuminant (built-ins raise :class:`ForbiddenError`)."""
        return self._run(P.delete("illuminants", name))


def _spec(local: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in local.items() if k != "self" and v is not None}
