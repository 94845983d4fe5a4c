"""Mitsuba 3 variant selection: which spectral backend renders, and the libLLVM it needs.

:func:`select_variant` (before ``mitsuba`` is first imported) picks ``cuda_ad_spectral`` when a
CUDA GPU is usable; else ``llvm_ad_spectral`` after locating a libLLVM ≥ 16 (``/usr/lib/llvm-*/lib``,
``/usr/lib/x86_64-linux-gnu``; LLVM ≤ 15 crashes Mitsuba 3.9) and setting ``DRJIT_LIBLLVM_PATH``;
else ``scalar_spectral`` with a warning (slow). ``ILLUMIX_MITSUBA_VARIANT`` forces a variant.
Every other renderer module gets Mitsuba through :func:`import_mitsuba`, so the variant is always
chosen first.
"""

from __future__ import annotations

import glob
import os
import re
import warnings
from typing import Any

from illumix.renderer_jobs.backends import RenderError  # noqa: F401 - raised here, defined with the protocol

VARIANTS = ("cuda_ad_spectral", "llvm_ad_spectral", "scalar_spectral")
MIN_LLVM = 16
LLVM_DIRS = ("/usr/lib/llvm-*/lib", "/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/local/lib",
             "/usr/lib/aarch64-linux-gnu")


def llvm_version(path: str) -> tuple[int, ...] | None:
    name = os.path.basename(path)
    m = re.match(r"libLLVM-(\d+)(?:\.(\d+))?(?:\.(\d+))?", name) or re.match(r"libLLVM\.so\.(\d+)(?:\.(\d+))?", name)
    if m:
        return tuple(int(g) for g in m.groups() if g is not None)
    m = re.search(r"/llvm-(\d+)/", path)
    if m and name.startswith("libLLVM") and ".so" in name:
        return (int(m.group(1)),)
    return None


def find_libllvm(min_version: int = MIN_LLVM, dirs: tuple[str, ...] = LLVM_DIRS) -> tuple[str, tuple[int, ...]] | None:
    """The newest shared libLLVM with major version ≥ ``min_version``: ``(path, version)`` or None.

    Looks at ``libLLVM*.so*`` in ``dirs`` (globs allowed). Static archives and LLVM ≤ 15 are refused.
    """
    found: list[tuple[tuple[int, ...], str]] = []
    for d in dirs:
        for p in glob.glob(os.path.join(d, "libLLVM*.so*")):
            v = llvm_version(p)
            if v is None or v[0] < min_version or not os.path.isfile(p):
                continue
            found.append((v, p))
    if not found:
        return None
    found.sort(key=lambda t: (t[0], -len(t[1])), reverse=True)
    v, p = found[0]
    return p, v


def _cuda_available() -> bool:
    if os.environ.get("CUDA_VISIBLE_DEVICES", None) in ("", "-1"):
        return False
    if not (glob.glob("/dev/nvidia[0-9]*") or glob.glob("/usr/lib/x86_64-linux-gnu/libcuda.so*")):
        return False
    return True


_STATE: dict[str, Any] = {}


def select_variant(prefer: str | None = None) -> str:
    """Choose and activate a spectral Mitsuba variant (see module docstring); returns its name.

    ``prefer`` (or ``ILLUMIX_MITSUBA_VARIANT``) forces one of :data:`VARIANTS`. Idempotent.
    """
    if "variant" in _STATE and prefer in (None, _STATE["variant"]):
        return _STATE["variant"]
    forced = prefer or os.environ.get("ILLUMIX_MITSUBA_VARIANT") or None
    if forced is not None and forced not in VARIANTS:
        raise RenderError(f"unknown Mitsuba variant {forced!r}; choose one of {', '.join(VARIANTS)}")
    candidates = [forced] if forced else list(VARIANTS)
    if "llvm_ad_spectral" in candidates:
        env = os.environ.get("DRJIT_LIBLLVM_PATH")
        env_v = llvm_version(env) if env else None
        if env and os.path.isfile(env) and (env_v is None or env_v[0] >= MIN_LLVM):
            _STATE["libllvm"] = env
        else:
            hit = find_libllvm()
            if hit is None:
                if forced:
                    raise RenderError(f"variant llvm_ad_spectral needs libLLVM >= {MIN_LLVM} (found none in "
                                      f"{', '.join(LLVM_DIRS)}); on Debian: apt-get install libllvm19")
                candidates.remove("llvm_ad_spectral")
            else:
                if env:
                    warnings.warn(f"DRJIT_LIBLLVM_PATH={env} is LLVM {env_v[0] if env_v else '?'} (< {MIN_LLVM}, "
                                  f"crashes Mitsuba); using {hit[0]}", stacklevel=2)
                os.environ["DRJIT_LIBLLVM_PATH"] = hit[0]
                _STATE["libllvm"] = hit[0]
    if "cuda_ad_spectral" in candidates and not forced and not _cuda_available():
        candidates.remove("cuda_ad_spectral")
    import mitsuba as mi

    errors = []
    for v in candidates:
        try:
            mi.set_variant(v)
            if v != "scalar_spectral":
                # Touch the backend: a missing GPU / bad LLVM fails here rather than mid-render.
                import drjit as dr

                dr.eval(mi.Float(1.0) + 1.0)
        except Exception as exc:  # noqa: BLE001 — any failure means "try the next variant"
            errors.append(f"{v}: {exc}")
            continue
        if v == "scalar_spectral":
            warnings.warn("Mitsuba: no GPU and no libLLVM >= 16 found; using scalar_spectral (slow). "
                          "Install libllvm19 for the vectorised CPU variant.", stacklevel=2)
        _STATE["variant"] = v
        return v
    raise RenderError("no usable Mitsuba spectral variant: " + "; ".join(errors))


def import_mitsuba():
    """``(mitsuba, drjit)`` with the variant selected (:func:`select_variant`)."""
    select_variant()
    import drjit as dr
    import mitsuba as mi

    return mi, dr


def libllvm_path() -> str | None:
    """The libLLVM the ``llvm_ad_spectral`` variant runs on (None before selection or on other variants)."""
    return _STATE.get("libllvm")
