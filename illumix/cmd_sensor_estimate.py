"""``illumix sensors estimate``: a camera's spectral sensitivities from its colour matrices (DNG
``ColorMatrix1/2``, or what a raw file carries), written as a rawtoaces camera JSON."""

from __future__ import annotations

import json
import os
from pathlib import Path

import typer

from illumix.consoles import make_console
from illumix.errors import UserError

console = make_console(stderr=True)


def estimate(
    out: Path = typer.Option(..., "--out", help="Camera JSON to write (rawtoaces format: upload it, or put it in "
                                                "ILLUMIX_SENSOR_PATH)."),
    color_matrix: str | None = typer.Option(None, "--color-matrix", help="XYZ -> camera, DNG convention: nine "
                                                                           "numbers m11,m12,…,m33 (rows R, G, B)."),
    calibration_illuminant: str = typer.Option("D65", "--calibration-illuminant",
                                               help="The illuminant --color-matrix was calibrated under (DNG "
                                                    "CalibrationIlluminant1), e.g. D65, A, D50."),
    color_matrix_2: str | None = typer.Option(None, "--color-matrix-2", help="A second matrix (DNG ColorMatrix2)."),
    calibration_illuminant_2: str | None = typer.Option(None, "--calibration-illuminant-2",
                                                        help="The illuminant of --color-matrix-2, e.g. A."),
    from_raw: Path | None = typer.Option(None, "--from-raw", help="A DNG (its ColorMatrix1/2 and calibration "
                                                                  "illuminants) or any raw file LibRaw reads (its Adobe-derived D65 matrix)."),
    chart_photo: list[Path] | None = typer.Option(None, "--chart-photo", help="A photo of a ColorChecker Classic "
                                                  "under --illuminant: a raw file LibRaw reads, or a linear camera-RGB "
                                                  "TIFF/.npy. The chart is found automatically, or give --corners. "
                                                  "Repeat for several photos (one --illuminant each, or one for all)."),
    illuminant: list[str] | None = typer.Option(None, "--illuminant", help="The light the chart photo was taken under."),
    corners: list[str] | None = typer.Option(None, "--corners", help="The chart's patch-area corners in the photo's "
                                                                     "pixels: x1,y1,…,x4,y4 (top-left at dark skin, "
                                                                     "top-right, bottom-right, bottom-left); one per "
                                                                     "--chart-photo. Default: found automatically."),
    exclude: str | None = typer.Option(None, "--exclude", help="Comma-separated measured cameras to leave out of "
                                                               "the prior (an honest leave-one-out)."),
    prior: str | None = typer.Option(None, "--prior", help="Folders of measured cameras (rawtoaces JSON) for the "
                                                           "prior, separated by the path separator (default: "
                                                           "ILLUMIX_SENSOR_PATH)."),
    name: str | None = typer.Option(None, "--name", help="The camera's name (default: the --out file's stem)."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON summary on stdout."),
) -> None:
    """Estimate a camera's spectral sensitivities from its colour matrices, under a prior learned from
    measured cameras (bench/SENSORS.md measures how close it comes)."""
    from illumix.retarget.errors import SpectralError
    from illumix.sensor_estimate.camera_file import write_camera
    from illumix.sensor_estimate.run import EstimateRequest, collect_matrices, run_estimate

    try:
        matrices, model = collect_matrices(from_raw, color_matrix, calibration_illuminant, color_matrix_2,
                                           calibration_illuminant_2)
        chart = _chart(chart_photo, illuminant, corners)
        if not matrices and chart is None:
            raise UserError("give --color-matrix (with --calibration-illuminant), --from-raw FILE or --chart-photo FILE")
        folders = [Path(p) for p in (prior or os.environ.get("ILLUMIX_SENSOR_PATH", "")).split(os.pathsep) if p]
        if not folders:
            raise UserError("no measured cameras for the prior: give --prior DIR (rawtoaces camera JSON files, "
                            "e.g. rawtoaces-data/data/camera) or set ILLUMIX_SENSOR_PATH")
        req = EstimateRequest(name=name or out.stem, matrices=matrices, prior=folders,
                              exclude=[s.strip() for s in (exclude or "").split(",") if s.strip()],
                              sensor_model=model, chart=chart)
        doc, summary = run_estimate(req)
        write_camera(out, doc)
    except SpectralError as exc:
        raise UserError(str(exc)) from None
    console.print(f"wrote {out}: {summary['name']} from {summary['matrices']} matrix(es), prior of "
                  f"{summary['prior_cameras']} cameras; posterior std at most {summary['max_std']:.3f} of the peak",
                  highlight=False)
    if as_json:
        print(json.dumps({**summary, "out": str(out)}))


def _chart(photos: list[Path] | None, illuminants: list[str] | None, corners: list[str] | None):
    """``[(patch means (24, 3), illuminant)]`` of the ``--chart-photo`` files, or None."""
    from illumix.retarget.errors import SpectralError
    from illumix.sensor_estimate.chart import find_patches, parse_corners, patch_means, read_linear

    photos, illuminants, corners = photos or [], illuminants or [], corners or []
    if not photos:
        if illuminants or corners:
            raise UserError("--illuminant and --corners go with --chart-photo")
        return None
    if len(illuminants) not in (1, len(photos)):
        raise UserError(f"--chart-photo needs --illuminant (the light it was taken under): one for all "
                        f"{len(photos)} photos or one each, got {len(illuminants)}")
    if corners and len(corners) != len(photos):
        raise UserError(f"--corners: one per --chart-photo ({len(photos)}), got {len(corners)}; or none to find "
                        "the charts automatically")
    lights = illuminants * len(photos) if len(illuminants) == 1 else illuminants
    out = []
    for i, (photo, light) in enumerate(zip(photos, lights)):
        try:
            image = read_linear(photo)
            patches = patch_means(image, parse_corners(corners[i])) if corners else find_patches(image)
        except SpectralError as exc:
            raise UserError(f"{photo}: {exc}") from None
        out.append((patches, light))
    return out
