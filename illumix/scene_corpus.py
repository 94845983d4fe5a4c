"""A dataset config → its scenes: generated rooms (cached as scene files) and the config's scene files.

Generated rooms are written once to a scenes directory (``<store>/.illumix-scenes/`` by default) as
``room-NNNNNN.yaml``, each atomically (a temporary file renamed into place), with a first comment
line recording the generator version and the hash of the generator config:

    # illumix.scenegen version=1 config=3f2a…  (generated; regenerated when either differs)

A resumed run reads the cached file instead of generating again (the probe costs seconds per room);
a file that is missing, unreadable or written by another generator version or config is generated
again. The files are ordinary scene files: ``illumix render`` takes them.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from illumix.errors import UserError
from illumix.scene_files import load_scene_file, write_yaml

SCENES_DIR = ".illumix-scenes"
HEADER = "# illumix.scenegen version={version} config={config}"


def config_hash(gen) -> str:
    """sha256 (16 hex digits) of a :class:`~scenegen.generate.GeneratorConfig`."""
    return hashlib.sha256(json.dumps(gen.model_dump(mode="json"), sort_keys=True).encode()).hexdigest()[:16]


def room_name(seed: int) -> str:
    return f"room-{seed:06d}"


def header(gen) -> str:
    from illumix.scenegen import GENERATOR_VERSION

    return HEADER.format(version=GENERATOR_VERSION, config=config_hash(gen))


def _cached(path: Path, want: str) -> bool:
    try:
        with path.open(encoding="utf-8") as f:
            return f.readline().rstrip("\n") == want
    except (OSError, UnicodeDecodeError):
        return False


def room(seed: int, gen, out_dir: Path | None, *, write: bool = True):
    """Room ``seed``: ``(scene, status)`` with status ``"cached"`` (read from ``out_dir``),
    ``"generated"`` (and written there unless ``write`` is False) or ``"regenerated"`` (the cached
    file was from another generator version or config, or unreadable)."""
    from illumix.scene.load import load_scenes
    from illumix.scene.schema import SceneError
    from illumix.scenegen.generate import generate_scene

    want = header(gen)
    path = out_dir / f"{room_name(seed)}.yaml" if out_dir is not None else None
    status = "generated"
    if path is not None and path.exists():
        if _cached(path, want):
            try:
                return load_scenes(path)[0], "cached"
            except SceneError:
                pass
        status = "regenerated"
    try:
        scene = generate_scene(seed, gen)
    except SceneError as exc:  # a generator bug: name the seed, say how to reproduce
        raise UserError(f"generated room seed {seed}: {str(exc).splitlines()[0]}") from None
    if path is not None and write:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_yaml(scene.model_dump(mode="json"), path, first_line=want)
    return scene, status


@dataclass
class Corpus:
    scenes: list = field(default_factory=list)
    generated: int = 0
    cached: int = 0
    files: int = 0


def build(config, config_dir: Path, scenes_dir: Path | None, *, limit: int | None = None, write: bool = True,
          on_room: Callable[[str, str], None] | None = None, on_start: Callable[[int], None] | None = None) -> Corpus:
    """The scenes of a :class:`~illumix.dataset_config.DatasetConfig`: its generated rooms (at most
    ``limit`` scenes in all, generated rooms first), then the scenes of its files. ``on_start(n)``
    gets the number of rooms to make, ``on_room(name, status)`` is called after each."""
    from illumix.scene.schema import SceneError

    out = Corpus()
    seeds = list(config.generated.seeds) if config.generated is not None else []
    if limit is not None:
        seeds = seeds[:limit]
    if on_start:
        on_start(len(seeds))
    for seed in seeds:
        scene, status = room(seed, config.generated.generator, scenes_dir, write=write)
        out.scenes.append(scene)
        if status == "cached":
            out.cached += 1
        else:
            out.generated += 1
        if on_room:
            on_room(scene.name, status)
    for name in config.scenes:
        if limit is not None and len(out.scenes) >= limit:
            break
        p = Path(name) if Path(name).is_absolute() else config_dir / name
        try:
            got = load_scene_file(p)
        except SceneError as exc:
            raise UserError(f"scenes: {name}: {exc}") from None
        out.files += 1
        out.scenes += got[: None if limit is None else limit - len(out.scenes)]
    names = [s.name for s in out.scenes]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise UserError(f"scenes: two scenes are named {dup[0]!r}" + (f" (and {len(dup) - 1} more)" if len(dup) > 1 else "")
                        + "; every scene in a dataset needs its own name (rename one in its file)")
    return out
