"""The Zarr cube store: layout, chunking, metadata schema, dtype policy, integrity (issue: Cube store).

Public API::

    from illumix.store import CubeStore, CubeMeta, ViewMeta, StoreError
    st = CubeStore.open("./illumix-store", mode="a")

See :mod:`store.cubestore` (the store), :mod:`store.schema` (metadata), :mod:`store.codec` (dtype
policy), :mod:`store.layout` (layout, chunking, compression), :mod:`store.backend` (atomic
publication), :mod:`store.registry` (uploaded sensors/illuminants), :mod:`store.report`
(``info``/``verify``).
"""

from illumix.store.cubestore import CubeStore
from illumix.store.errors import StoreError, StoreKeyError, StoreWriteError
from illumix.store.registry import Registry, RegistryEntry
from illumix.store.schema import SCHEMA_VERSION, BandStats, CubeMeta, RendererInfo, StorageInfo, ViewMeta

__all__ = ["CubeStore", "CubeMeta", "ViewMeta", "RendererInfo", "BandStats", "StorageInfo", "StoreError",
           "StoreKeyError", "StoreWriteError", "Registry", "RegistryEntry", "SCHEMA_VERSION"]
