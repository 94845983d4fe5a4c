"""illumix client: fetch mixed-illuminant colour-constancy samples from an illumix service.

>>> from illumix_client import Client
>>> with Client("http://127.0.0.1:8000") as c:                          # doctest: +SKIP
...     s = c.sample(scene="synth", sensor="XYZ", pair=("A", "D65"), crop=(0, 0, 32, 32))
...     s.raw.shape, s.gain.shape, s.meta["illuminants"][0]["illuminant"]
((32, 32, 3), (32, 32, 3), 'A')

Needs only numpy and httpx. ``IllumixDataset`` (PyTorch) is imported on first use and needs
``pip install "clients/python[torch]"`` (the CPU-only torch: README); without torch it raises a
``ModuleNotFoundError`` that says so.
"""

from __future__ import annotations

from illumix_client._protocol import RetryPolicy
from illumix_client.aio import AsyncClient
from illumix_client.client import Client
from illumix_client.draw import (
    CIE_FLUORESCENT,
    CIE_LED,
    CIE_STANDARD,
    IlluminantPool,
    ViewInfo,
)
from illumix_client.errors import (
    AuthError,
    ConflictError,
    ConnectionFailed,
    ForbiddenError,
    IllumixError,
    InvalidRequestError,
    NotFoundError,
    RequestTimeoutError,
    RequestTooLargeError,
    ServerError,
)
from illumix_client.sample import OUTPUTS, Sample

__version__ = "0.1.0"

__all__ = [
    "AsyncClient", "AuthError", "CIE_FLUORESCENT", "CIE_LED", "CIE_STANDARD", "Client", "ConflictError",
    "ConnectionFailed", "ForbiddenError", "IlluminantPool", "IllumixError",
    "InvalidRequestError", "NotFoundError", "OUTPUTS", "RequestTimeoutError", "RequestTooLargeError",
    "RetryPolicy", "Sample", "ServerError", "ViewInfo",
]


def __getattr__(name: str):
    if name == "IllumixDataset":  # torch is imported only when the dataset is asked for
        from illumix_client.torch_dataset import IllumixDataset

        return IllumixDataset
    raise AttributeError(f"module 'illumix_client' has no attribute {name!r}")
