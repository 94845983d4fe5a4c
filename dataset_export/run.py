"""The whole export (what ``illumix export`` runs): plan, compose, write, split, card, manifest.

Resumable (:mod:`dataset_export.journal`): a rerun with the same options skips every place whose files are
complete and unchanged, and an interrupted file never looks complete. ``on_progress(total, label)``
is called once with ``label=None`` and the number of items, then once per item done.
"""

from __future__ import annotations

import datetime
import errno
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from illumix.dataset_export.errors import ExportError, require
from illumix.dataset_export.formats import EXPORT_FORMATS
from illumix.dataset_export.journal import MANIFEST, Journal
from illumix.dataset_export.plan import parse_lightings, plan_places
from illumix.dataset_export.splits import empty_split_warnings, split_scenes

#: The sensor model raw frames get unless ``--noise`` says otherwise: a typical phone sensor's shot and
#: read noise (:data:`retarget.sensor_model.NOISE_PRESETS`), so that a model trained on the export meets
#: noise as it will in photographs; ``None`` (``--noise none``): noise-free frames.
DEFAULT_NOISE = "phone"


@dataclass
class ExportOptions:
    store: str
    out: str
    format: str = "lsmi"
    sensors: list[str] = field(default_factory=lambda: ["Nikon 5100 (NPL)"])
    pairs: str | None = None
    illuminants: str | None = None
    count: int | None = None
    size: tuple[int, int] | None = None
    seed: int = 0
    gt: str | None = None  # LSMI's target: None (= "mixture"), "physical" or "formula" (dataset_export.lsmi_target)
    split: tuple[float, float, float] = (0.7, 0.15, 0.15)
    noise: str | None = DEFAULT_NOISE
    bayer: str | None = "RGGB"  # None: --format dng writes LinearRaw RGB
    exr_dtype: str = "float32"


def _check_out(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / ".illumix-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        full = "free space on that disk or " if exc.errno in (errno.ENOSPC, errno.EDQUOT) else ""
        raise ExportError(f"cannot write into {out} ({exc.strerror or exc}); {full}choose a writable folder") from None


#: options a format ignores (set to anything but their default, they are refused), as the CLI names them
_CAMERA_FLAGS = (("--sensors", "sensors"), ("--pairs", "pairs"), ("--illuminants", "illuminants"),
                 ("--noise", "noise"), ("--gt", "gt"), ("--bayer", "bayer"))


def _check_flags(o: ExportOptions, fmt) -> None:
    """Refuse an option ``fmt`` would ignore: the cubes (``exr``) take no camera, illuminant, sensor
    model, ground truth or mosaic; frames take no ``--exr-dtype``; only ``dng`` frames a mosaic."""
    default = ExportOptions(store="", out="")
    if fmt.raw_ext is None:
        ignored = [flag for flag, name in _CAMERA_FLAGS if getattr(o, name) != getattr(default, name)]
        why = "writes the store's spectral cubes, which no camera, illuminant or sensor model changes"
    else:
        ignored = [flag for flag, name in (("--exr-dtype", "exr_dtype"), ("--bayer", "bayer"))
                   if getattr(o, name) != getattr(default, name) and (name != "bayer" or not fmt.bayer)]
        why = "writes camera frames" + ("" if fmt.bayer else " without a mosaic")
    if ignored:
        raise ExportError(f"--format {fmt.name} {why}, so {', '.join(ignored)} would change nothing; "
                          f"drop {', '.join(ignored)}")


def _check_size(size: tuple[int, int] | None) -> None:
    """Frames (and resampled cubes) within the service's limits on an output (its ``Limits``: side and
    pixels), checked before anything is written."""
    from illumix.engine.limits import Limits

    if size is None:
        return
    lim = Limits()
    w, h = size
    if max(w, h) > lim.max_side or w * h > lim.max_pixels:
        raise ExportError(f"--size {w}x{h} exceeds the service's limits (side <= {lim.max_side}, pixels <= "
                          f"{lim.max_pixels}); give a smaller --size, e.g. {min(w, lim.max_side)}x{min(h, lim.max_side)}")


def _open_store(url: str):
    from illumix.store import CubeStore, StoreError

    try:
        if not CubeStore.exists(url):
            raise ExportError(f"no illumix store at {url}; render one with `illumix demo` or `illumix render --store {url}`")
        return CubeStore.open(url, mode="r")
    except StoreError as exc:
        raise ExportError(f"store {url}: {exc}") from None


def _check_names(st, sensors, illuminants, place) -> None:
    """Unknown or unusable sensor / illuminant names (or files given by path): one line with the close
    matches, before any work."""
    from illumix.engine.local_library import LocalLibrary

    lib = LocalLibrary(st)
    grid = st.cube_meta(place.scene, place.view, place.groups[0]).spectral_grid
    for s in sensors:
        lib.sensor(s, grid)
    for n in sorted(illuminants):
        lib.illuminant(n, grid)


def drawn_sampling(pairs: str | None) -> str | None:
    """``planckian``/``extended`` for ``--pairs draw:<sampling>`` (:mod:`dataset_export.illuminant_draws`), else None."""
    from illumix.dataset_export.illuminant_draws import SAMPLINGS

    if not pairs or not pairs.strip().lower().startswith("draw"):
        return None
    kind = pairs.strip().lower().partition(":")[2].strip() or "planckian"
    if kind not in SAMPLINGS:
        raise ExportError(f"--pairs {pairs!r}: draw:<sampling> takes {' or '.join(SAMPLINGS)}, e.g. draw:extended")
    return kind


def _draw(st, places, sampling: str, out: Path) -> dict[str, tuple[tuple[str, str], dict[str, bytes]]]:
    """Per place, ``((daylight, artificial) names, {file path: CSV bytes})``: a pair drawn with the place's
    seed; a drawn SPD that is no built-in name becomes ``OUT/illuminants/<name>.csv``, named by its path."""
    from illumix.dataset_export.illuminant_draws import draw_pair

    grid = st.cube_meta(places[0].scene, places[0].view, places[0].groups[0]).spectral_grid
    out_abs = out.resolve()
    result = {}
    for p in places:
        names, files = [], {}
        for d in draw_pair(p.seed, sampling, grid):
            if d.builtin:
                names.append(d.name)
                continue
            path = str(out_abs / "illuminants" / f"{d.name}.csv")
            names.append(path)
            files[path] = d.csv()
        result[p.name] = (tuple(names), files)
    return result


def _views(st) -> list[tuple[str, str, tuple[str, ...]]]:
    return [(s, v, tuple(st.groups(s, v))) for s in st.scenes() for v in st.views(s) if st.groups(s, v)]


def _places(st, views, o: ExportOptions, fmt, sampling: str | None, out: Path):
    """``(places, skipped, drawn)``: the plan (:mod:`dataset_export.plan`) with each place's lighting —
    given, or drawn per place (:func:`_draw`) for ``--pairs draw:<sampling>``."""
    if sampling and o.illuminants:
        raise ExportError("give either --pairs or --illuminants, not both")
    lightings = parse_lightings(o.pairs, o.illuminants) if fmt.raw_ext and not sampling else [()]
    if sampling:  # one draw per place: as many distinct "lightings" per view as places asked for
        lightings = [(f"draw{i}", sampling) for i in range(o.count or 1)]
    # --pairs (and the default pair A,D65) light groups as /sample?pair= does; --illuminants in group order
    places, skipped = plan_places(views, lightings, count=o.count, seed=o.seed,
                                  pair=bool(fmt.raw_ext) and not o.illuminants)
    drawn = _draw(st, places, sampling, out) if sampling else {}
    return [replace(p, lighting=drawn[p.name][0]) for p in places] if sampling else places, skipped, drawn


def export_dataset(o: ExportOptions, on_progress: Callable[[int, str | None], None] | None = None) -> dict:
    """Write the dataset ``o`` describes into ``o.out``; returns the summary (also in the card)."""
    fmt = EXPORT_FORMATS[o.format]
    if o.gt not in (None, "mixture", "physical", "formula"):
        raise ExportError(f"--gt {o.gt!r}: choose mixture (default), physical or formula")
    if o.gt == "mixture":  # the default, recorded as before (a resumed export keeps its options)
        o = replace(o, gt=None)
    for module in fmt.modules:
        require(module, f"--format {fmt.name}")
    _check_size(o.size)
    out = Path(o.out)
    st = _open_store(o.store)
    views = _views(st)
    if not views:
        raise ExportError(f"store {o.store} has no complete view; render some with `illumix render`")
    _check_flags(o, fmt)
    sampling = drawn_sampling(o.pairs) if fmt.raw_ext else None
    places, skipped, drawn = _places(st, views, o, fmt, sampling, out)
    warnings = []
    if o.count is not None and len(places) < o.count:
        more = "give more --illuminants/--pairs or render more views" if fmt.raw_ext else "render more views"
        warnings.append(f"--count {o.count}: the store has {len(places)} distinct view × lighting combination(s) "
                        f"for these illuminants; each is exported once ({len(places)} places, no copies); {more} "
                        "for more")
    splits = split_scenes({p.scene for p in places}, o.split, o.seed)
    if fmt.raw_ext:
        from illumix.dataset_export.raw_layout import check_frames

        _check_names(st, o.sensors, {n for p in places for n in p.lighting if n not in drawn.get(p.name, ((), {}))[1]},
                     places[0])
        check_frames(st, places, o, fmt)
    _check_out(out)
    params = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(o).items() if k != "out"}
    params["format"] = fmt.name
    if fmt.raw_ext is None:
        params |= {"sensors": [], "noise": None, "bayer": None, "gt": None}
    journal = Journal(out, params)
    for _, files in drawn.values():  # drawn SPDs that are no built-in name: files given by path
        for path, data in files.items():
            journal.write_bytes(str(Path(path).relative_to(out.resolve())), data)
    summary = {"format": fmt.name, "store": o.store, "seed": o.seed, "split": ",".join(map(str, o.split)),
               "size": f"{o.size[0]}x{o.size[1]}" if o.size else None,
               "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
               "skipped": [f"{s['scene']}/{s['view']}: {s['why']}" for s in skipped], "samples": [],
               "warnings": warnings, "sampling": sampling}
    by_split = {name: [p.name for p in places if splits[p.scene] == name] for name in ("train", "val", "test")}
    summary["splits"] = by_split
    if fmt.raw_ext is None:
        from illumix.dataset_export.exr_layout import export_cubes

        export_cubes(st, places, journal, o, summary, on_progress)
    else:
        from illumix.dataset_export.raw_layout import export_frames

        export_frames(st, places, journal, o, fmt, summary, by_split, on_progress)
    summary["warnings"] += empty_split_warnings(summary["splits"], o.split, len({p.scene for p in places}))
    from illumix.dataset_export.card import dataset_card

    journal.write_bytes("README.md", dataset_card(summary).encode())
    journal.write_json(MANIFEST, journal.manifest({"created": summary["created"], "counts": summary["counts"],
                                                   "splits": summary["splits"], "skipped": summary["skipped"],
                                                   "samples": summary.pop("samples")}))
    summary["out"] = str(out)
    summary["files"] = len(journal.files)
    return summary
