"""``illumix validate --out DIR``: the renderer against closed form (thesis §5.1 analogue)."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.table import Table

from illumix.consoles import make_console
from illumix.errors import UserError
from illumix.options import choice_option, described, seed_option, wavelengths_option
from illumix.renderer_jobs.modes import BACKENDS

console = make_console(stderr=True)


def validate(
    out: Path = typer.Option(..., "--out", help="Directory for validation.json (created if missing)."),
    sensor: str = typer.Option("Nikon 5100 (NPL)", "--sensor", help="Sensor name or rawtoaces JSON / CSV file."),
    illuminants: str = typer.Option("D65,A,FL2,FL11,FL12,blackbody:2300", "--illuminants",
                                    help="Comma-separated illuminants (names, blackbody:K, daylight:K, CSV)."),
    spp: int = typer.Option(64, "--spp", min=16, help="Paths per pixel of the chart render."),
    seed: int = seed_option("--seed", "Render seed of the chart."),
    resolution: str = typer.Option("192x128", "--resolution", help="WIDTHxHEIGHT of the chart render."),
    incidence: float = typer.Option(30.0, "--incidence", min=0.0, max=80.0,
                                    help="Angle of the light from the chart normal, degrees."),
    wavelengths: str = wavelengths_option(),
    backend: str = choice_option(BACKENDS, "--backend", f"Renderer of the chart — {described(BACKENDS)}."),
    as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON on stdout."),
) -> None:
    """Render a Lambertian ColorChecker under a distant light and compare it with closed form."""
    from illumix.cmd_render import require_renderer
    from illumix.renderer_jobs.jobs import parse_resolution
    from illumix.scene.schema import SceneError
    from illumix.renderer_jobs.validate import run_validation

    require_renderer(BACKENDS.canonical(backend))
    names = [s.strip() for s in illuminants.split(",") if s.strip()]
    if not names:
        raise UserError("--illuminants is empty; give e.g. D65,A")
    try:
        res = parse_resolution(resolution)
        result = run_validation(sensor, names, spp=spp, seed=seed, resolution=res, incidence_deg=incidence,
                                wavelengths=wavelengths, backend=backend)
    except SceneError as exc:
        raise UserError(str(exc)) from None
    except ValueError as exc:  # patch too small for the resolution
        from illumix.retarget.errors import SpectralError

        if isinstance(exc, SpectralError):
            raise
        raise UserError(str(exc)) from None
    try:
        out.mkdir(parents=True, exist_ok=True)
        path = out / "validation.json"
        path.write_text(json.dumps(result.to_dict(), indent=1))
    except OSError as exc:
        raise UserError(f"cannot write {out}/validation.json: {exc}") from None
    if as_json:
        print(json.dumps({"out": str(path), "summary": result.summary}))
        return
    table = Table("illuminant", "mean ΔE00", "max ΔE00", "mean rel R/G,B/G %", "mean angular °")
    for s in result.summary:
        table.add_row(s["illuminant"], f"{s['mean_delta_e00']:.4f}", f"{s['max_delta_e00']:.4f}",
                      f"{s['mean_relative_rg_bg_pct']:.4f}", f"{s['mean_angular_deg']:.4f}")
    make_console().print(table)  # the result, on stdout (`illumix validate … > table.txt`)
    console.print(f"wrote {path}")


def register(app: typer.Typer) -> None:
    app.command("validate")(validate)
