"""The Zarr cube store: layout, chunking, metadata schema, dtype policy, integrity (issue: Cube store).

Public API::

    from store import CubeStore, CubeMeta, ViewMeta, StoreError
    st = CubeStore.open("./illumix-store", mode="a")

See :mod:`store.cubestore` (the store), :mod:`store.schema` (metadata), :mod:`store.codec` (dtype
policy), :mod:`store.layout` (layout, chunking, compression), :mod:`store.backend` (atomic
publication), :mod:`store.registry` (uploaded sensors/illuminants), :mod:`store.report`
(``info``/``verify``).
"""

from store.cubestore import CubeStore
from store.errors import StoreError, StoreKeyError, StoreWriteError
from store.registry import Registry, RegistryEntry
from store.schema import SCHEMA_VERSION, BandStats, CubeMeta, RendererInfo, StorageInfo, ViewMeta

__all__ = ["CubeStore", "CubeMeta", "ViewMeta", "RendererInfo", "BandStats", "StorageInfo", "StoreError",
           "StoreKeyError", "StoreWriteError", "Registry", "RegistryEntry", "SCHEMA_VERSION"]
