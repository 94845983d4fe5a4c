"""``illumix export STORE OUT --format lsmi|dng|exr [--sensors …] [--pairs A,D65;… | --illuminants …]
[--count N] [--size WxH] [--seed S] [--gt mixture|physical|formula] [--split 0.7,0.15,0.15] [--noise …]
[--bayer RGGB|none] [--exr-dtype float32|float16] [--json]``.

Writes a frozen dataset from a cube store (:mod:`dataset_export`): the LSMI release's layout with TIFF
(``lsmi``) or Bayer DNG (``dng``) raws, or the store's spectral cubes as OpenEXR (``exr``); splits
by scene, ``manifest.json`` with every file's SHA-256, a dataset card ``README.md``. Resumable: run
it again after an interruption and it skips what is complete. A disk that refuses a write (full,
read-only, failing) stops it with one line naming the file (exit 2); only complete files stay, so
the same command resumes once there is space. Sensors and illuminants are names or files given by
path (:class:`engine.local_library.LocalLibrary`).
"""

from __future__ import annotations

import json
import re
import sys

import typer

from illumix.consoles import make_console
from illumix.dataset_export.formats import EXPORT_FORMATS
from illumix.errors import UserError, write_failure

console = make_console(stderr=True)


def _size(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d{1,5})\s*[xX]\s*(\d{1,5})\s*", text)
    if not m or 0 in (int(m[1]), int(m[2])):
        raise UserError(f"--size {text!r}: give WxH in pixels, e.g. 256x192")
    return int(m[1]), int(m[2])


PAIRS_HELP = ("Illuminant pairs, ';'-separated, e.g. \"A,D65;FL11,D50\" (default A,D65), lighting each view as "
              "/sample?pair= does: where its groups have kinds, the pair's daylight illuminant lights the daylight "
              "groups and the other the artificial ones, else the first two groups in order; each place draws one "
              "with the seed; an illuminant may be a CSV wavelength,value given by path. draw:planckian or "
              "draw:extended draws a daylight + artificial pair per place (extended: measured LEDs, fluorescents, "
              "gels, sky/sun daylight).")
GT_HELP = ("What LSMI's mixture files (the target its trainers read) hold: mixture (default: each light's share of "
           "the pixel's green), physical (fitted so that LSMI's model Σ mixture·Light is illumix's physical ground "
           "truth, bounce light included) or formula (thesis eq. 3.3 ground truth).")


def export(
    store: str = typer.Argument(..., help="Cube store directory or fsspec URL."),
    out: str = typer.Argument(..., help="Folder to write the dataset into (created; a rerun resumes)."),
    fmt: str = typer.Option("lsmi", "--format", help=f"{', '.join(EXPORT_FORMATS.choices())} (any case): "
                                                     "lsmi = LSMI layout with 16-bit TIFF raws, dng = the same with "
                                                     "Bayer DNG raws, exr = the store's spectral cubes as OpenEXR."),
    sensors: str | None = typer.Option(None, "--sensors",
                                       help="Comma-separated sensor names or camera files given by path (rawtoaces "
                                            "JSON, CSV wavelength,r,g,b), one camera folder each (`illumix sensors "
                                            "list`; default \"Nikon 5100 (NPL)\")."),
    pairs: str | None = typer.Option(None, "--pairs", help=PAIRS_HELP),
    illuminants: str | None = typer.Option(None, "--illuminants", help="Like --pairs with 1-3 illuminants per "
                                                                       "entry (one per lit group), e.g. \"A,D65,FL11;D50\"."),
    count: int | None = typer.Option(None, "--count", min=1, help="Places to write (default: every usable view once; "
                                                                  "more repeat views with other lightings; at most "
                                                                  "the distinct view × lighting combinations)."),
    size: str | None = typer.Option(None, "--size", help="Frame size WxH (area resampling; default as rendered; "
                                                   "at most the service's 4096 a side)."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of places, lightings, splits and noise."),
    gt: str | None = typer.Option(None, "--gt", help=GT_HELP),
    split: str = typer.Option("0.7,0.15,0.15", "--split", help="Train,val,test fractions of the scenes."),
    noise: str | None = typer.Option(None, "--noise", help="Camera noise model of the raw frames: phone (default: shot "
                                                           "and read noise, black level 64, white level 4095), low, high, "
                                                           "key:value;… as /sample's noise=, or none (noise-free)."),
    bayer: str | None = typer.Option(None, "--bayer", help="CFA pattern of --format dng: RGGB (default), BGGR, "
                                                             "GRBG or GBRG; none: LinearRaw DNGs (RGB per pixel, no "
                                                             "mosaic)."),
    exr_dtype: str = typer.Option("float32", "--exr-dtype", help="float32 (exact) or float16 (clipped at 65504) "
                                                                 "for --format exr."),
    as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON on stdout."),
) -> None:
    """Write a frozen dataset (LSMI layout, DNG or spectral EXR) with splits, manifest and card."""
    from illumix.dataset_export.errors import ExportWriteError
    from illumix.dataset_export.run import export_dataset
    from illumix.progress import progress_bar

    opts = _options(store, out, fmt, sensors, pairs, illuminants, count, size, seed, gt, split, noise, bayer, exr_dtype)
    name = opts.format
    quiet = as_json and not console.is_terminal
    with progress_bar(console, disable=quiet) as prog:
        task = None

        def on_progress(n: int, label: str | None) -> None:
            nonlocal task
            if label is None:
                task = prog.add_task(f"export {name}", total=n, last="")
            else:
                prog.update(task, advance=n, last=label)

        try:
            summary = export_dataset(opts, on_progress)
        except ExportWriteError as exc:  # a full, read-only or failing disk: complete files are kept
            raise UserError(write_failure(exc.filename, exc, elsewhere="choose another OUT folder")) from None
    for w in summary["warnings"]:
        print(f"illumix: warning: {w}", file=sys.stderr)
    console.print(f"exported {summary['counts']} into {summary['out']} ({summary['files']} files; "
                  f"{len(summary['skipped'])} skipped)", highlight=False)
    if as_json:
        print(json.dumps({k: v for k, v in summary.items() if k not in ("layout", "reading")}))


def _options(store, out, fmt, sensors, pairs, illuminants, count, size, seed, gt, split, noise, bayer, exr_dtype):
    """The :class:`ExportOptions` of the command's arguments, each checked (one line naming the flag)."""
    from illumix.dataset_export.run import ExportOptions
    from illumix.dataset_export.splits import parse_fractions
    from illumix.engine.spec import parse_noise
    from illumix.retarget.sensor_model import BAYER_PATTERNS

    from illumix.dataset_export.run import DEFAULT_NOISE

    name = EXPORT_FORMATS.canonical(fmt)
    if gt is not None and gt.lower() not in ("mixture", "physical", "formula"):
        raise UserError(f"--gt {gt!r}: choose mixture (default), physical or formula")
    if exr_dtype not in ("float32", "float16"):
        raise UserError(f"--exr-dtype {exr_dtype!r}: choose float32 or float16")
    noise = DEFAULT_NOISE if noise is None else None if noise.strip().lower() == "none" else noise
    if noise is not None:
        parse_noise(noise)
    given = {}  # the rest keep ExportOptions' defaults (export_dataset refuses what a format ignores)
    if sensors is not None:
        given["sensors"] = [s.strip() for s in sensors.split(",") if s.strip()]
        if not given["sensors"]:
            raise UserError("--sensors: give at least one sensor name, e.g. --sensors \"Nikon 5100 (NPL)\"")
    if bayer is not None:
        given["bayer"] = None if bayer.strip().lower() == "none" else BAYER_PATTERNS.canonical(bayer)
    gt = None if gt is None or gt.lower() == "mixture" else gt.lower()
    return ExportOptions(store=store, out=out, format=name, pairs=pairs, illuminants=illuminants,
                         count=count, size=_size(size), seed=seed, gt=gt,
                         split=parse_fractions(split), noise=noise, exr_dtype=exr_dtype, **given)


def register(app: typer.Typer) -> None:
    app.command("export")(export)
