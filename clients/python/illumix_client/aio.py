"""The asynchronous twin of :class:`illumix_client.Client`, over ``httpx.AsyncClient``.

Same methods, same parameters, same exceptions and retry policy; every method is a coroutine.
"""

from __future__ import annotations

from asyncio import sleep as _sleep  # a module global, so tests can patch the waits
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import httpx

from illumix_client import _protocol as P
from illumix_client.client import DEFAULT_TIMEOUT, _spec
from illumix_client.sample import Sample


class AsyncClient:
    """``async with AsyncClient(base_url, token=None, timeout=...) as c: s = await c.sample(...)``.

    See :class:`illumix_client.Client` for the meaning of every method and parameter.
    """

    def __init__(self, base_url: str = "http://127.0.0.1:8000", token: str | None = None,
                 timeout: float | httpx.Timeout | None = DEFAULT_TIMEOUT,
                 retry: P.RetryPolicy | None = None,
                 transport: httpx.AsyncBaseTransport | None = None,
                 wire_format: str = "arrays", keep_float16: bool = False) -> None:
        self.base_url = P.check_base_url(base_url)
        self.wire_format, self.keep_float16 = P.check_wire_format(wire_format), bool(keep_float16)
        self.retry = retry or P.RetryPolicy()
        self._http = httpx.AsyncClient(base_url=self.base_url, headers=P.headers(token), timeout=timeout,
                                       transport=transport)

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc) -> None:
        await self.aclose()

    async def aclose(self) -> None:
        await self._http.aclose()

    async def _run(self, call: P.Call) -> Any:
        return await P.run_async(call, self.retry, self.base_url, self._send, _sleep)

    async def _send(self, call: P.Call) -> httpx.Response:
        if not call.buffered:
            return await self._http.request(call.method, call.path, **call.request_kwargs())
        request = self._http.build_request(call.method, call.path, **call.request_kwargs())
        return await P.aread_body(call, await self._http.send(request, stream=True))

    async def health(self) -> dict:
        return await self._run(P.health())

    async def scenes(self) -> list[dict]:
        return await self._run(P.scenes())

    async def sensors(self) -> dict:
        return await self._run(P.sensors())

    async def sensor(self, name: str) -> dict:
        return await self._run(P.sensor(name))

    async def illuminants(self) -> dict:
        return await self._run(P.illuminants())

    async def sample(self, scene: str | None = None, view: str | None = None, *, seed: int | None = None,
                     sensor: str | None = None, pair: str | Sequence[str] | None = None,
                     illuminants: str | Sequence[str] | None = None,
                     intensities: str | Sequence[float] | None = None,
                     crop: str | Sequence[int] | None = None, size: str | Sequence[int] | None = None,
                     outputs: str | Sequence[str] | None = None, gt: str | None = None,
                     denoise: str | None = None,
                     exposure: str | float | None = None,
                     noise: str | Mapping[str, float] | None = None, bayer: str | None = None,
                     dtype: str | None = None) -> Sample:
        return await self._run(P.sample(_spec(locals()), self.wire_format, self.keep_float16))

    async def batch(self, specs: Iterable[Mapping[str, Any]]) -> list[Sample]:
        return await self._run(P.batch(specs, self.wire_format, self.keep_float16))

    async def image(self, output: str = "srgb", format: str = "png", **spec: Any) -> bytes:
        return await self._run(P.image(output, format, spec))

    async def upload_sensor(self, name: str, path: str | Path | bytes, overwrite: bool = False) -> dict:
        return await self._run(P.upload("sensors", name, path, overwrite))

    async def delete_sensor(self, name: str) -> dict:
        return await self._run(P.delete("sensors", name))

    async def upload_illuminant(self, name: str, path: str | Path | bytes, overwrite: bool = False) -> dict:
        return await self._run(P.upload("illuminants", name, path, overwrite))

    async def delete_illuminant(self, name: str) -> dict:
        return await self._run(P.delete("illuminants", name))
