"""``illumix evaluate STORE_OR_DATASET [--methods …] [--sensor …] [--pairs …] [--json] [--out DIR]``.

Scores white-balance methods (:mod:`evaluate`) on images composed from a cube store by the
service's own pipeline, or read from an exported LSMI-layout dataset: per-pixel angular error and
the thesis' ΔE00 grid (appendix B), per method and per illuminant pair; a markdown table (or
``--json``), and with ``--out`` the table, the JSON, box plots and error maps.
"""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

import typer

from illumix.consoles import make_console
from illumix.awb_eval.method_names import AWB_METHODS, DEFAULT_METHODS
from illumix.errors import UserError, write_failure

console = make_console(stderr=True)


def _grid(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d{1,4})\s*[xX]\s*(\d{1,4})\s*", text)
    if not m or int(m[1]) < 1 or int(m[2]) < 1:
        raise UserError(f"--grid {text!r}: give ROWSxCOLS, e.g. 4x4")
    return int(m[1]), int(m[2])


def _source(path: str, *, sensor, pairs, count, seed, size, gt, split, black_level, white_level):
    """A :class:`awb_eval.store_input.StoreCases` or :class:`awb_eval.lsmi_input.LsmiCases` for ``path``."""
    from illumix.awb_eval.lsmi_input import LsmiCases, is_lsmi

    local = Path(path.removeprefix("file://"))
    if "://" in path.removeprefix("file://") or (local / "zarr.json").is_file():
        lsmi_only = {"--split": split, "--black-level": black_level, "--white-level": white_level}
        given = [k for k, v in lsmi_only.items() if v is not None]
        if given:
            raise UserError(f"{', '.join(given)} apply to LSMI datasets; {path} is an illumix store")
        from illumix.awb_eval.store_input import StoreCases

        return StoreCases(path, sensor=sensor, pairs=pairs, count=count, seed=seed, size=size, gt=gt)
    if local.is_dir() and is_lsmi(local):
        given = [k for k, v in {"--size": size, "--gt": gt}.items() if v is not None]
        if given:
            raise UserError(f"{', '.join(given)} apply to illumix stores; {path} is an LSMI dataset")
        return LsmiCases(local, camera=sensor, pairs=pairs, count=count, seed=seed, split=split,
                         black_level=black_level, white_level=white_level)
    what = "does not exist" if not local.exists() else "is neither an illumix store (zarr.json at its root) " \
                                                         "nor an LSMI dataset (<camera>/meta.json)"
    raise UserError(f"{path} {what}; give a store rendered by `illumix render` or a folder written by "
                    "`illumix export --format lsmi`")


def evaluate(
    data: str = typer.Argument(..., metavar="STORE_OR_DATASET",
                               help="An illumix cube store (directory or fsspec URL) or an LSMI-layout dataset folder."),
    methods: str = typer.Option(", ".join(DEFAULT_METHODS), "--methods",
                                help=f"Comma-separated AWB methods (any case; aliases): {', '.join(AWB_METHODS.names)}; "
                                     "or a plug-in module.path:callable (raw (H,W,3) float32 → gain map (H,W,3))."),
    sensor: str | None = typer.Option(None, "--sensor", help="Store: the camera to compose for, a name or a camera "
                                                             "file given by path (default Nikon 5100 (NPL)); 'random': "
                                                             "each image its own camera drawn from the measured "
                                                             "cameras' prior (random:<seed + k>). LSMI: the camera "
                                                             "folder (default: the only one)."),
    pairs: str | None = typer.Option(None, "--pairs", help="Store: lightings separated by ';', each 'A,D65' (a pair "
                                                           "for the first two groups) or 'D65' (every group); default "
                                                           "\"A,D65;FL11,D50\"; an illuminant may be a CSV given by "
                                                           "path. LSMI: light sets, e.g. \"12;13\" (default all)."),
    count: int | None = typer.Option(None, "--count", min=1, help="Only N views (store) or places (LSMI), drawn with --seed."),
    seed: int = typer.Option(0, "--seed", min=0, max=2**63 - 1, help="Seed of the --count draw and of each sample."),
    size: str | None = typer.Option(None, "--size", help="Store: compose at WxH (area resampling), e.g. 320x240."),
    gt: str | None = typer.Option(None, "--gt", help="Store: ground truth physical or formula (default: the service's)."),
    split: str | None = typer.Option(None, "--split", help="LSMI: only places of this split (train, val, test)."),
    black_level: float | None = typer.Option(None, "--black-level", help="LSMI: black level (default: the template DNG's)."),
    white_level: float | None = typer.Option(None, "--white-level", help="LSMI: white level (default: the template DNG's)."),
    grid: str = typer.Option("4x4", "--grid", help="Patch-wise methods: ROWSxCOLS cells."),
    interpolation: str = typer.Option("bilinear", "--interpolation", metavar="[bilinear|nearest]",
                                      help="Patch-wise methods: cell estimates interpolated between cell centres, or "
                                           "constant per cell."),
    maps: int = typer.Option(3, "--maps", min=0, help="With --out: error-map figures for the first N images."),
    out: str | None = typer.Option(None, "--out", help="Write table.md, results.json, boxplots.png and maps/ here."),
    as_json: bool = typer.Option(False, "--json", help="Print the results as JSON on stdout instead of the table."),
) -> None:
    """Score white-balance methods on a store or an LSMI dataset: angular error and ΔE00 grid."""
    from illumix.awb_eval.report import aggregate, markdown

    t0 = time.perf_counter()
    chosen = _methods(methods, grid, interpolation, gt)
    labels = [m.label for m in chosen]
    source = _source(data, sensor=sensor, pairs=pairs, count=count, seed=seed, size=size,
                     gt=None if gt is None else gt.lower(), split=split, black_level=black_level, white_level=white_level)
    if out is not None:
        from illumix.awb_eval.outputs import prepare_folder

        out = Path(out)
        # after the input checks (a refused run leaves no folder), before scoring (an unwritable --out
        # fails in a second, not after the run)
        prepare_folder(out)
    res = _score(source, chosen, maps if out is not None else 0, quiet=as_json and not console.is_terminal)
    if not res.images:
        why = f"{res.skipped[0]['name']}: {res.skipped[0]['why']}" if res.skipped else "no images"
        raise UserError(f"{data}: no image could be scored ({len(res.skipped)} skipped; {why})")
    summary = aggregate(res, labels)
    doc = {"input": source.describe(), "settings": {"methods": labels, "grid": list(_grid(grid)),
                                                   "interpolation": interpolation},
           "white_points": summary["white_points"], "methods": summary["methods"], "pairs": summary["pairs"],
           "images": res.images, "skipped": res.skipped,
           "seconds": round(time.perf_counter() - t0, 3)}
    table = markdown(summary, title=f"AWB evaluation: {len(res.images)} images of {data}")
    if out is not None:
        written = _write(out, doc, table, res, labels)
        console.print(f"wrote {', '.join(written[:4])}{' …' if len(written) > 4 else ''} to {out}", highlight=False)
    _print(doc, table, as_json)
    if res.skipped:
        console.print(f"skipped {len(res.skipped)} image(s): {res.skipped[0]['name']}: {res.skipped[0]['why']}",
                      highlight=False)


def _write(out: Path, doc: dict, table: str, res, labels: list[str]) -> list[str]:
    """The ``--out`` folder (:func:`awb_eval.outputs.write_outputs`); a disk that refuses a file is one
    line, and the temporary file it was written under is removed (finished files stay whole)."""
    from illumix.awb_eval.outputs import write_outputs

    try:
        return write_outputs(out, doc, table, res, labels)
    except OSError as exc:
        for tmp in [*out.glob(".*.tmp"), *out.glob("maps/.*.tmp")]:
            tmp.unlink(missing_ok=True)
        raise UserError(write_failure(exc.filename or out, exc, elsewhere="give another --out",
                                      rerun="run the evaluation again")) from None


def _methods(methods: str, grid: str, interpolation: str, gt: str | None) -> list:
    """The chosen methods, after the option checks (one line each)."""
    from illumix.awb_eval.method_names import split_methods
    from illumix.awb_eval.methods import resolve
    from illumix.awb_eval.statistical import INTERPOLATIONS

    if interpolation not in INTERPOLATIONS:
        raise UserError(f"--interpolation {interpolation!r}: choose {' or '.join(INTERPOLATIONS)}")
    if gt is not None and gt.lower() not in ("physical", "formula"):
        raise UserError(f"--gt {gt!r}: choose physical or formula")
    names = split_methods(methods)
    if not names:
        raise UserError(f"--methods {methods!r} names no method; e.g. \"Gray World, Ground Truth\"")
    return resolve(names, grid=_grid(grid), interpolation=interpolation)


def _score(source, chosen: list, maps: int, quiet: bool):
    """Every image of ``source`` scored by every method, with a progress bar."""
    from illumix.awb_eval.run import evaluate as run
    from illumix.progress import progress_bar

    with progress_bar(console, disable=quiet, transient=True) as prog:
        task = prog.add_task("evaluating", total=len(source), last="")
        return run(source, chosen, maps=maps, on_case=lambda case, name: prog.update(task, advance=1, last=name))


def _print(doc: dict, table: str, as_json: bool) -> None:
    """The results on stdout: JSON, the table rendered on a terminal, or its markdown when piped."""
    if as_json:
        print(json.dumps(doc))
    elif (stdout := make_console()).is_terminal:
        from rich.markdown import Markdown

        stdout.print(Markdown(table))
    else:  # piped: the markdown itself, ready to paste
        print(table, end="")


def register(app: typer.Typer) -> None:
    app.command("evaluate")(evaluate)
