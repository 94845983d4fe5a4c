"""Where Blender's Python is: the Cycles backend's one dependency outside illumix's environment.

``bpy`` 4.5 (Blender as a Python module, PyPI) pins ``numpy < 2``, while illumix needs numpy 2
(zarr 3.1, colour-science 0.4.7), so pip cannot install both into one environment. The Cycles
worker (:mod:`renderer_jobs.cycles.worker`) therefore runs in its own interpreter, found as:

1. ``$ILLUMIX_BLENDER_PYTHON``, a Python that can ``import bpy`` (when set, nothing else is tried);
2. this interpreter, if it can import ``bpy`` itself;
3. the environment ``bash scripts/install.sh --blender`` creates:
   ``$ILLUMIX_BLENDER_VENV`` (default ``~/.cache/illumix/blender-venv``).
"""

from __future__ import annotations

import functools
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

from illumix.scene.schema import SceneError

INSTALL_HINT = ("install it with `bash scripts/install.sh --blender` (a Python environment with bpy 4.5 "
                "at ~/.cache/illumix/blender-venv), or set ILLUMIX_BLENDER_PYTHON to a Python that can import bpy")


def default_venv() -> Path:
    return Path(os.environ.get("ILLUMIX_BLENDER_VENV", Path.home() / ".cache" / "illumix" / "blender-venv"))


@functools.lru_cache(maxsize=8)
def _version_of(python: str) -> str | None:
    try:
        out = subprocess.run([python, "-c", "import bpy; print('BPY', bpy.app.version_string)"],
                             capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired):
        return None
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("BPY ")]
    return lines[-1][4:].strip() if out.returncode == 0 and lines else None


def find_blender_python(required: bool = True) -> tuple[str, str] | None:
    """``(python executable, Blender version)`` for the Cycles worker, or None (``required=False``).
    Raises :class:`SceneError` with the install hint when there is none."""
    env = os.environ.get("ILLUMIX_BLENDER_PYTHON")
    candidates = [env] if env else []  # when set, it is the only candidate
    if not env and importlib.util.find_spec("bpy") is not None:
        candidates.append(sys.executable)
    if not env:
        candidates.append(str(default_venv() / "bin" / "python"))
    for c in candidates:
        if c and Path(c).exists():
            v = _version_of(c)
            if v:
                return c, v
    if env:
        msg = f"ILLUMIX_BLENDER_PYTHON={env} cannot import bpy; point it at a Python with bpy 4.5, or unset it"
    else:
        msg = f"the cycles backend needs Blender (bpy), which was not found; {INSTALL_HINT}"
    if required:
        raise SceneError(msg)
    return None
