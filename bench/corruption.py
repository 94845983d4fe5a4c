"""Corruption sweep: is every flipped byte found by `store verify`, and is none served as data?

    python bench/corruption.py [--flips 200] [--seed 0]

Builds a small store like a rendered one (2 views of 96×72, 2 light groups each with illumination
cubes, float16 and float32 cubes, AOVs, an uploaded sensor), then for each trial flips one random byte
(XOR with a random non-zero value) at a random offset of a random file — chunks and metadata
documents alike, files drawn uniformly — and checks: (1) ``store verify`` reports a problem (or the
store refuses to open, naming the damaged root document), (2) everything the store still serves
through its read API (cubes, AOVs, view and cube metadata, group lists, the registry entry) equals
the undamaged store's. The byte is restored after each trial. Human lines on stderr; JSON last.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from illumix.retarget.grid import DEFAULT_GRID  # noqa: E402
from illumix.store import CubeMeta, CubeStore, StoreError, ViewMeta  # noqa: E402
from illumix.store.report import verify  # noqa: E402
from illumix.store.synth import synthetic_cube  # noqa: E402

H, W = 72, 96
VIEWS, GROUPS = ("v0", "v1"), ("daylight", "lamp")


def build(root: Path) -> None:
    st = CubeStore.open(root, mode="a", tile=32)
    common = dict(grid=DEFAULT_GRID.to_dict(), renderer={"name": "synthetic", "version": "1"}, spp=16, seed=0,
                  emission=[1.0] * DEFAULT_GRID.n_bands, emission_name="flat")
    rng = np.random.default_rng(0)
    for i, v in enumerate(VIEWS):
        aovs = {"mask": rng.random((H, W)) > 0.1, "depth": rng.random((H, W)).astype(np.float32),
                "albedo": rng.random((H, W, 3)).astype(np.float32)}
        st.write_view("room", v, ViewMeta(width=W, height=H, fov=50.0, groups=list(GROUPS)), aovs)
        for j, g in enumerate(GROUPS):
            cube = synthetic_cube(H, W, seed=10 * i + j)
            st.write_cube("room", v, g, cube, CubeMeta(**common), illumination=cube * 0.5 + 0.01,
                          dtype_policy="float32" if j else "auto")
    st.registry("sensors").put("cam", b"wavelength,r,g,b\n400,0.1,0.2,0.3\n700,0.3,0.2,0.1\n", "csv")


def served(root: Path) -> dict:
    """Everything the store serves (None where a read is refused)."""
    try:
        st = CubeStore.open(root, mode="r")
    except StoreError:
        return {}
    reads = {"sensor": lambda: st.registry("sensors").get("cam")}
    for v in VIEWS:
        reads[f"{v}/meta"] = lambda v=v: st.view_meta("room", v).model_dump()
        reads[f"{v}/groups"] = lambda v=v: st.groups("room", v)
        for a in ("mask", "depth", "albedo"):
            reads[f"{v}/{a}"] = lambda v=v, a=a: st.read_aov("room", v, a)
        for g in GROUPS:
            reads[f"{v}/{g}/meta"] = lambda v=v, g=g: st.cube_meta("room", v, g).model_dump()
            for kind in ("transport", "illumination"):
                reads[f"{v}/{g}/{kind}"] = lambda v=v, g=g, k=kind: st.read_cube("room", v, g, kind=k)
    out = {}
    for key, call in reads.items():
        try:
            out[key] = call()
        except Exception:  # noqa: BLE001 - any refusal is "not served"
            out[key] = None
    return out


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    return a == b


def kind_of(rel: str) -> str:
    if "/c/" in rel:
        return "chunk"
    if "_checksums" in rel:
        return "manifest"
    return "metadata"


def trial(root: Path, rel: str, rng: np.random.Generator, clean: dict) -> tuple[bool, list[str]]:
    """Flip one byte of ``rel``: ``(found by verify, keys served altered)``; the byte restored."""
    path = root / rel
    data = bytearray(path.read_bytes())
    at = int(rng.integers(len(data)))
    data[at] ^= int(rng.integers(1, 256))
    original = path.read_bytes()
    path.write_bytes(bytes(data))
    try:
        try:
            found = not verify(CubeStore.open(root, mode="r"))["ok"]
        except StoreError:
            found = True  # the store does not open: its root document, named in the error
        got = served(root)
        altered = [k for k, v in got.items() if v is not None and not _equal(v, clean[k])]
    finally:
        path.write_bytes(original)
    return found, altered


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flips", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "store"
        build(root)
        assert verify(CubeStore.open(root, mode="r"))["ok"]
        clean = served(root)
        files = sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())
        rng = np.random.default_rng(args.seed)
        kinds, missed, altered = Counter(), [], []
        for i in range(args.flips):
            rel = files[int(rng.integers(len(files)))]
            kinds[kind_of(rel)] += 1
            found, bad = trial(root, rel, rng, clean)
            if not found:
                missed.append(rel)
            altered += [f"{rel}: {k}" for k in bad]
            if (i + 1) % 50 == 0:
                print(f"{i + 1}/{args.flips} flips: {len(missed)} missed, {len(altered)} served altered",
                      file=sys.stderr, flush=True)
    out = {"flips": args.flips, "files": len(files), "by_kind": dict(kinds), "found_by_verify": args.flips - len(missed),
           "missed": missed, "served_altered": len(altered), "altered": altered[:20],
           "seconds": round(time.perf_counter() - t0, 1)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
