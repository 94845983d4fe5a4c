"""The sensor and illuminant names of commands run on this machine (``illumix export``, ``illumix
evaluate``): the service's :class:`~engine.library.Library` (built-ins, ``ILLUMIX_SENSOR_PATH``
files, the store's uploads, ``random:<seed>``), plus files given by path — a rawtoaces camera JSON
or a ``wavelength,r,g,b`` CSV as a sensor, a ``wavelength,value`` CSV as an illuminant — read by the
same functions every other command reads them with (:func:`retarget.sensors.get_sensor`,
:func:`retarget.illuminants.illuminant_spd`), so a name means the same thing to all commands.

The service never resolves paths (a request must not read the server's files): it keeps the plain
:class:`~engine.library.Library`. A name is a path when no built-in, parametric or uploaded name
matches it and it names a file, or ends in ``.json``/``.csv`` (a missing file is then one line
naming the path). Cache keys hold the file's resolved path and content hash: an edited file is
never served from a stale cache.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
from illumix.engine.library import RANDOM, Library
from illumix.retarget import illuminants as ill
from illumix.retarget import sensors as sen
from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import SpectralGrid

SUFFIXES = (".json", ".csv")


class LocalLibrary(Library):
    """:class:`Library` that also takes files by path (module docstring)."""

    def local_file(self, kind: str, name: str) -> Path | None:
        """The file ``name`` stands for (``kind`` ``"sensors"`` or ``"illuminants"``), or ``None`` when it
        is a name the service knows (or no file and no file name at all)."""
        if kind == "sensors":
            known = name.lower().startswith(RANDOM + ":") or self.is_builtin_sensor(name)
        else:
            known = ill.is_builtin(name) or name.partition(":")[0].lower() in ill.PARAMETRIC
        if known or not (Path(name).is_file() or name.lower().endswith(SUFFIXES)):
            return None
        if name in self._registry(kind).names():  # an upload of that name wins, as in the service
            return None
        return Path(name)

    def sensor(self, name: str, grid: SpectralGrid) -> tuple[sen.Sensor, str]:
        path = self.local_file("sensors", name)
        if path is None:
            return super().sensor(name, grid)
        s = sen.get_sensor(name, grid)  # a missing file: "sensor file '…' does not exist; check the path"
        return s, _key(path)

    def illuminant(self, name: str, grid: SpectralGrid) -> tuple[np.ndarray, str]:
        path = self.local_file("illuminants", name)
        if path is None:
            return super().illuminant(name, grid)
        if not path.is_file():
            raise SpectralError(f"illuminant file {name!r} does not exist; check the path")
        return ill.illuminant_spd(name, grid), _key(path)


def _key(path: Path) -> str:
    """``file:<resolved path>:<sha1 of its bytes>`` (module docstring)."""
    return f"file:{path.resolve()}:{hashlib.sha1(path.read_bytes()).hexdigest()}"

