"""``LocalClient``: the client's interface composed in-process from a store, with no HTTP.

For single-machine training: ``IllumixDataset(store="./illumix-store")`` composes each sample here,
with the service's own code (:mod:`engine.sampling`), so a sample is identical to what
``GET /sample`` answers for the same parameters. Needs the physics core: ``pip install
"illumix-client[local]"`` (or the illumix package itself); ``import illumix_client`` alone still
imports no server code.

Decoded cubes and whole-frame projections are cached in the process (``cache_mb``, as ``illumix
serve --cache-mb``). :meth:`LocalClient.warm` decodes every cube once; do it before a DataLoader
forks its workers and they share the decoded cubes (copy-on-write pages) instead of decoding them
again each. The store's listings and metadata are read once per client (a training run composes
from a fixed store; re-reading them was ~0.4 ms of a ~2 ms crop): reopen it to see new renders.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from illumix_client.errors import (
    IllumixError,
    InvalidRequestError,
    NotFoundError,
    RequestTooLargeError,
    ServerError,
)
from illumix_client.sample import Sample, as_specs, encode_spec

try:
    from pydantic import ValidationError

    from illumix.engine import catalogue
    from illumix.engine.context import make_context
    from illumix.engine.errors import Busy, NotFound, TooLarge
    from illumix.engine.sampling import build, plan, price
    from illumix.engine.spec import SampleSpec
    from illumix.engine.torch_sampling import refusal as torch_refusal
    from illumix.retarget.errors import SpectralError, UnknownName
    from illumix.store import CubeStore, StoreError, StoreKeyError
except ImportError as exc:  # pragma: no cover - depends on the install
    raise ImportError(f"the local mode needs the illumix physics core ({exc}); install it with "
                      "`pip install \"illumix-client[local]\"` or `pip install illumix`") from None


class LocalClient:
    """:class:`illumix_client.Client`'s read methods (``scenes``, ``sensors``, ``illuminants``,
    ``sample``, ``batch``) over a store path or fsspec URL, composed in this process.

    cache_mb, projection_mb : the cache bounds (see ``illumix serve``).
    device, device_cache_mb : compose with torch on ``device`` (``"cuda"``, ``"cpu"``;
    :mod:`engine.torch_sampling`: outputs raw, gain, mask, weights, illum, mixture; arrays are
    tensors on the device) with up to ``device_cache_mb`` of cubes kept there; ``None`` (default):
    the service's numpy path.
    """

    def __init__(self, store: str, *, cache_mb: int = 2048, projection_mb: int | None = None,
                 device: str | None = None, device_cache_mb: int = 8192) -> None:
        try:
            if not CubeStore.exists(store):
                raise NotFoundError(f"no illumix store at {store}; render one with `illumix render --store {store}`")
            self.store = CubeStore.open(store, mode="r")
        except StoreError as exc:
            raise IllumixError(str(exc)) from None
        self.url = store
        try:
            self.ctx = make_context(_ReadOnceMetadata(self.store), cache_mb=cache_mb, projection_mb=projection_mb, device=device,
                                    device_cache_mb=device_cache_mb)
        except (ImportError, RuntimeError) as exc:
            raise IllumixError(f"device={device!r}: {exc}") from None
        self.torch = self.ctx.torch

    # -- what the store holds ------------------------------------------------------------------
    def scenes(self) -> dict:
        return _call(lambda: catalogue.scenes(self.ctx))

    def sensors(self) -> dict:
        return _call(lambda: catalogue.sensors(self.ctx))

    def illuminants(self) -> dict:
        return _call(lambda: catalogue.illuminants(self.ctx))

    # -- samples -------------------------------------------------------------------------------
    def sample(self, **spec: Any) -> Sample:
        """One sample; ``spec`` as for :meth:`illumix_client.Client.sample` (``dtype`` shapes the wire,
        which the local mode has not: its arrays are always float32)."""
        return self._one(encode_spec(spec))

    def batch(self, specs: Iterable[Mapping[str, Any]]) -> list[Sample]:
        """Samples for each spec, in order (no batch-size limit: they are composed one by one)."""
        return [self._one(s) for s in as_specs(specs)]

    def _one(self, wire: dict[str, Any]) -> Sample:
        def run() -> Sample:
            spec = SampleSpec(**wire)
            if self.torch is not None and (why := torch_refusal(spec)) is not None:
                raise InvalidRequestError(f"device={self.torch.device.type}: {why} (device=None)", 422)
            p = plan(spec, self.ctx)
            price(p, self.ctx)  # holds the cubes it finds cached, as the service does
            arrays, meta = build(p, self.ctx, keep_device=True)
            s = Sample(meta=meta if "meta" in spec.outputs else {})
            for k, v in arrays.items():
                setattr(s, k, v)  # numpy arrays, or tensors on the device
            return s
        return _call(run)

    def warm(self, sensors: list[str] | None = None, illuminants: list[str] | None = None,
             progress: bool = False) -> dict:
        """Decode every cube /sample reads by default into the cache (until it is full); with
        ``sensors`` and ``illuminants`` also project every view through each pair into the
        projection cache, so crops drawn from that pool are slices from the first one on.
        Returns :func:`engine.warm.warm_cache`'s counts plus ``"projections"``."""
        from illumix.engine.warm import warm_cache, warm_projections

        log = print if progress else None
        out = warm_cache(self.ctx, log=log)
        if sensors and illuminants and self.torch is None:
            out["projections"] = warm_projections(self.ctx, list(sensors), list(illuminants), log=log)["projections"]
        return out

    def close(self) -> None:
        self.ctx.cache.clear()
        if self.ctx.projections is not None:
            self.ctx.projections.clear()

    def __enter__(self) -> LocalClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _call(fn):
    """Run ``fn``, raising the client's typed errors for what the service would answer 4xx/5xx."""
    try:
        return fn()
    except IllumixError:
        raise
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(x) for x in first.get("loc", ()))
        raise InvalidRequestError(f"{where}: {first.get('msg')}", 422, code="invalid_parameter") from None
    except (UnknownName, NotFound, StoreKeyError) as exc:
        raise NotFoundError(str(exc), 404, code="not_found") from None
    except TooLarge as exc:
        raise RequestTooLargeError(str(exc), 413, code="too_large") from None
    except SpectralError as exc:
        raise InvalidRequestError(str(exc), 422, code="invalid_parameter") from None
    except Busy as exc:
        raise ServerError(str(exc), 503, code="busy") from None
    except StoreError as exc:
        raise IllumixError(f"store problem: {exc}; run `illumix store verify`", 503, code="store_damaged") from None


class _ReadOnceMetadata:
    """The store with its listings and metadata read once: a training run composes from a fixed
    store, and re-reading them (~0.4 ms of a ~2 ms crop) for every sample buys nothing. Reopen the
    client to see cubes rendered since."""

    def __init__(self, store) -> None:
        self._store = store
        self._memo: dict = {}

    def _once(self, name: str, *args):
        key = (name, *args)
        if key not in self._memo:
            self._memo[key] = getattr(self._store, name)(*args)
        return self._memo[key]

    def scenes(self):
        return list(self._once("scenes"))

    def views(self, scene: str):
        return list(self._once("views", scene))

    def groups(self, scene: str, view: str):
        return list(self._once("groups", scene, view))

    def cube_meta(self, scene: str, view: str, group: str):
        return self._once("cube_meta", scene, view, group)

    def view_meta(self, scene: str, view: str):
        return self._once("view_meta", scene, view)

    def has_scene(self, scene: str) -> bool:
        return self._once("has_scene", scene)

    def has_view(self, scene: str, view: str) -> bool:
        return self._once("has_view", scene, view)

    def __getattr__(self, name: str):
        return getattr(self._store, name)  # reads of pixels, registries, url, …

