"""``illumix sensors estimate``'s work: matrices in, a camera JSON out."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from illumix.retarget.errors import SpectralError
from illumix.retarget.grid import DEFAULT_GRID


@dataclass
class EstimateRequest:
    """``matrices``: ``[(ColorMatrix (3, 3) XYZ → camera, calibration illuminant name)]``; ``prior``:
    folders of measured cameras; ``exclude``: their names left out of the prior."""

    name: str
    matrices: list[tuple[np.ndarray, str]]
    prior: list[Path]
    exclude: list[str] = field(default_factory=list)
    components: int = 12
    samples: int = 64
    sensor_model: dict | None = None  # a DNG's black/white level, CFA and NoiseProfile (noise=camera)
    chart: list[tuple[np.ndarray, str]] | None = None  # chart photos: (24, 3) patch means, illuminant


def parse_matrix(text: str, flag: str) -> np.ndarray:
    """Nine numbers ``m11,m12,…,m33`` (rows R, G, B) → ``(3, 3)``."""
    try:
        vals = [float(x) for x in text.replace(";", ",").split(",") if x.strip()]
    except ValueError:
        raise SpectralError(f"{flag} {text!r}: give nine numbers m11,m12,…,m33 (rows R, G, B)") from None
    if len(vals) != 9 or not np.all(np.isfinite(vals)):
        raise SpectralError(f"{flag}: give nine finite numbers m11,m12,…,m33 (rows R, G, B), got {len(vals)}")
    return np.asarray(vals).reshape(3, 3)


def collect_matrices(raw: Path | None, cm: str | None, ill: str, cm2: str | None, ill2: str | None,
                     spell=lambda name: "--" + name.replace("_", "-")) -> tuple[list, dict | None]:
    """``(matrices, the raw file's sensor model)`` of the inputs: a raw file's (a DNG's ColorMatrix1/2,
    another raw's LibRaw D65 matrix) and the matrices given as text; ``spell`` names a parameter the
    way the caller's user wrote it (``--color-matrix`` on the command line, ``color_matrix`` over HTTP)."""
    from illumix.sensor_estimate.camera_file import dng_sensor_model, raw_matrices

    matrices, model = [], None
    if raw is not None:
        matrices += raw_matrices(raw)
        model = dng_sensor_model(raw)
    if cm is not None:
        matrices.append((parse_matrix(cm, spell("color_matrix")), ill))
    if (cm2 is None) != (ill2 is None):
        raise SpectralError(f"{spell('color_matrix_2')} and {spell('calibration_illuminant_2')} go together")
    if cm2 is not None:
        matrices.append((parse_matrix(cm2, spell("color_matrix_2")), ill2))
    return matrices, model


def run_estimate(req: EstimateRequest) -> tuple[dict, dict]:
    """``(camera JSON document, summary)`` of an estimate."""
    from illumix.retarget.illuminants import illuminant_spd
    from illumix.sensor_estimate import fit
    from illumix.sensor_estimate.camera_file import camera_json
    from illumix.sensor_estimate.prior import learn_prior, load_measured

    grid = DEFAULT_GRID
    measured = load_measured(req.prior, grid).without(req.exclude)
    prior = learn_prior(measured, req.components)
    refl = fit.reflectance_columns(fit.FIT_REFLECTANCES, grid)
    if req.chart:
        if req.matrices:
            raise SpectralError("give a chart photo or colour matrices, not both")
        photos = [(responses, illuminant_spd(light, grid)) for responses, light in req.chart]
        est = fit.estimate_from_patches(prior, photos, refl, samples=req.samples)
    else:
        pairs = [(m, illuminant_spd(ill, grid)) for m, ill in req.matrices]
        est = fit.estimate(prior, pairs, refl, fit.xyz_observer(grid), samples=req.samples)
    provenance = {"method": "Gaussian linear model on a PCA prior of measured cameras (sensor_estimate.fit)",
                  "matrices": [{"color_matrix": np.round(m, 6).tolist(), "calibration_illuminant": ill}
                               for m, ill in req.matrices],
                  **({"chart_photos": [{"illuminant": light, "patch_means": np.round(resp, 6).tolist()}
                                       for resp, light in req.chart]} if req.chart else {}),
                  "prior_cameras": len(prior.cameras), "excluded": sorted(req.exclude),
                  "components": len(prior.variance), "fit_reflectances": fit.FIT_REFLECTANCES,
                  "relative_residual": round(est.residual, 6), "noise_scale": fit.NOISE_SCALE,
                  **({"sensor_model": req.sensor_model} if req.sensor_model else {})}
    doc = camera_json(req.name, grid, est.curves, est.samples, provenance)
    summary = {"name": req.name, "prior_cameras": len(prior.cameras), "excluded": sorted(req.exclude),
               "matrices": len(req.matrices), "chart_photo": bool(req.chart), "chart_photos": len(req.chart or []),
               "relative_residual": round(est.residual, 6),
               "max_std": round(float(est.samples.std(axis=0).max() / est.curves.max()), 5)}
    return doc, summary
