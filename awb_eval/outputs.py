"""The ``--out DIR`` folder of an evaluation: ``table.md``, ``results.json``, ``boxplots.png`` and
``maps/<image>.png``. Every file is written to a temporary name and renamed into place, so an
interrupted run never leaves a half-written file; a rerun overwrites them with its own results.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from illumix.awb_eval.run import Results
from illumix.retarget.errors import SpectralError


def write_text(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def save_figure(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.name}.tmp")
    fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


def safe_name(name: str) -> str:
    """A file name for an image label (``demo-room-0/corner A,D65`` → ``demo-room-0_corner_A-D65``)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name.replace(",", "-")).strip("_") or "image"


def prepare_folder(out: Path) -> None:
    """Check, before any image is scored, that the ``--out`` folder can be written: matplotlib is
    installed, the folder exists or can be created, and a file can be written into it (probed with a
    temporary file, removed again). Raises :class:`SpectralError` with one line otherwise."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise SpectralError("--out draws plots with matplotlib, which is not installed: "
                            "pip install 'illumix[evaluate]'") from None
    if out.exists() and not out.is_dir():
        raise SpectralError(f"--out {out} is a file; give a directory")
    probe = out / ".illumix-write-probe.tmp"
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise SpectralError(f"--out {out}: cannot write there ({exc.strerror or exc}); "
                            "give a folder you can write to") from None


def write_outputs(out: Path, doc: dict, table: str, res: Results, labels: list[str]) -> list[str]:
    """Write the folder (checked beforehand by :func:`prepare_folder`); returns the paths written
    (relative to ``out``)."""
    from illumix.awb_eval.plots import box_plots, error_map

    out.mkdir(parents=True, exist_ok=True)
    written = ["table.md", "results.json"]
    write_text(out / "table.md", table)
    write_text(out / "results.json", json.dumps(doc, indent=1) + "\n")
    if res.images:
        save_figure(box_plots(res.images, labels), out / "boxplots.png")
        written.append("boxplots.png")
    if res.maps:
        (out / "maps").mkdir(exist_ok=True)
        for m in res.maps:
            rel = f"maps/{safe_name(m.name)}.png"
            save_figure(error_map(m), out / rel)
            written.append(rel)
    return written
