"""Optional dependencies, and the error that says how to install one that is missing."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

TORCH_MISSING = (
    "IllumixDataset needs PyTorch, which is not installed; install the client's torch extra: "
    'pip install "clients/python[torch]" from the illumix repository (or pip install "illumix-client[torch]"). '
    "On a machine without a GPU install the CPU build first, which is a fraction of the size of the default CUDA "
    "build: pip install torch --index-url https://download.pytorch.org/whl/cpu")


def import_torch():
    """``torch``, or a :class:`ModuleNotFoundError` naming the extra to install (:data:`TORCH_MISSING`)
    where torch itself is missing (an error inside an installed torch is raised as it is)."""
    try:
        import torch
    except ModuleNotFoundError as exc:
        if exc.name != "torch":
            raise
        raise ModuleNotFoundError(TORCH_MISSING, name="torch") from None
    return torch


@contextmanager
def torch_threads(n: int | None) -> Iterator[None]:
    """torch's intra-op threads set to ``n`` inside the block, restored after (``None``: unchanged)."""
    import torch

    before = torch.get_num_threads()
    change = n is not None and n != before
    if change:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        if change:
            torch.set_num_threads(before)
