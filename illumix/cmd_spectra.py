"""``illumix illuminants|sensors list``, ``illumix whitepoint``, ``illumix ccm``."""

from __future__ import annotations

import json

import typer

from illumix.consoles import make_console
from illumix.options import choice_option
from illumix.retarget.ccm_methods import CCM_METHODS, DEFAULT_TRAINING_SET

# The spectral libraries (colour-science, numpy) are imported inside the commands: `--help` must not
# wait for them.
console = make_console()
illuminants_app = typer.Typer(help="The illuminant library.", no_args_is_help=True)
sensors_app = typer.Typer(help="The sensor library.", no_args_is_help=True)

SENSOR_HELP = "Sensor name (see `illumix sensors list`) or a rawtoaces JSON / CSV wavelength,r,g,b file"
ILLUMINANT_HELP = "Illuminant name (see `illumix illuminants list`), blackbody:K, daylight:K or a CSV file"


@illuminants_app.command("list")
def illuminants_list(as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List the built-in illuminants and the parametric forms."""
    from illumix.retarget import illuminants as ill
    from illumix.retarget.errors import SpectralError

    names, unusable = [], {}
    for name in ill.builtin_names():
        try:
            ill.illuminant_spd(name)
            names.append(name)
        except SpectralError as exc:  # e.g. ISO 7589 weighting functions stop at 690 nm
            unusable[name] = str(exc)
    parametric = {k: {"min_kelvin": lo, "max_kelvin": hi} for k, (lo, hi) in ill.PARAMETRIC.items()}
    if as_json:
        print(json.dumps({"illuminants": names, "parametric": parametric, "not_on_grid": unusable}))
        return
    console.print(f"[bold]{len(names)} tabulated illuminants[/] (colour-science SDS_ILLUMINANTS):")
    console.print(", ".join(names))
    if unusable:
        console.print(f"[dim]not usable on the default grid (data does not cover it): {', '.join(unusable)}[/]")
    for k, v in parametric.items():
        console.print(f"[bold]{k}:<K>[/]  {v['min_kelvin']:g}–{v['max_kelvin']:g} K")
    console.print("or a CSV file wavelength,value")


@sensors_app.command("list")
def sensors_list(as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List the built-in sensors (plus files in ILLUMIX_SENSOR_PATH) and whether they cover the grid."""
    from rich.table import Table

    from illumix.retarget import sensors as sen
    from illumix.retarget.errors import SpectralError

    rows = []
    for name in sen.builtin_names():
        try:
            s = sen.get_sensor(name)
            rows.append({"name": name, "source": s.source, "ok": True, "problem": None})
        except SpectralError as exc:
            rows.append({"name": name, "source": "", "ok": False, "problem": str(exc)})
    if as_json:
        print(json.dumps({"sensors": rows}))
        return
    table = Table("name", "usable", "source / problem")
    for r in rows:
        table.add_row(r["name"], "yes" if r["ok"] else "[red]no[/]", r["source"] if r["ok"] else r["problem"])
    console.print(table)
    if not sen.sensor_dirs():
        console.print("Add camera files with ILLUMIX_SENSOR_PATH=/dir/of/rawtoaces/json, or pass a file path.")


def whitepoint(
    sensor: str = typer.Option(..., "--sensor", help=SENSOR_HELP),
    illuminant: str = typer.Option(..., "--illuminant", help=ILLUMINANT_HELP),
    as_json: bool = typer.Option(False, "--json", help="Print JSON: rgb, r_over_g, b_over_g."),
) -> None:
    """The sensor's white point of an illuminant (thesis eq. 3.2): R/G, B/G and RGB with G = 1."""
    from illumix.retarget import illuminants as ill
    from illumix.retarget import sensors as sen
    from illumix.retarget.groundtruth import white_point

    s = sen.get_sensor(sensor)
    wp = white_point(s.weights(), ill.illuminant_spd(illuminant, s.grid), what=illuminant)
    result = {"sensor": s.name, "illuminant": illuminant, "rgb": [float(x) for x in wp],
              "r_over_g": float(wp[0]), "b_over_g": float(wp[2])}
    if as_json:
        print(json.dumps(result))
    else:
        console.print(f"{s.name} under {illuminant}: R/G = {wp[0]:.5f}, B/G = {wp[2]:.5f}  "
                      f"(RGB {wp[0]:.5f}, 1, {wp[2]:.5f})")


def ccm(
    sensor: str = typer.Option(..., "--sensor", help=SENSOR_HELP),
    illuminant: str = typer.Option(..., "--illuminant", help=ILLUMINANT_HELP),
    training: str = typer.Option(DEFAULT_TRAINING_SET, "--training",
                                 help="Reflectance training set name or CSV file."),
    method: str = choice_option(CCM_METHODS, "--method",
                                "White Preserving keeps white exactly (M·1 = 1); Unconstrained: plain least squares."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON: matrix, fit_delta_e00_mean."),
) -> None:
    """Fit the CCM (white-balanced raw → linear sRGB) of a sensor under an illuminant."""
    from illumix.retarget import illuminants as ill
    from illumix.retarget import sensors as sen
    from illumix.retarget.ccm import fit_ccm
    from illumix.retarget.reflectances import get_reflectances

    s = sen.get_sensor(sensor)
    _, refl = get_reflectances(training, s.grid)
    fit = fit_ccm(s.weights(), ill.illuminant_spd(illuminant, s.grid), refl, s.grid, method=method)
    result = {"sensor": s.name, "illuminant": illuminant, "training_set": training, "method": method,
              "matrix": fit.matrix.round(8).tolist(), "fit_delta_e00_mean": fit.delta_e00_mean,
              "fit_delta_e00_max": fit.delta_e00_max}
    if as_json:
        print(json.dumps(result))
        return
    for row in fit.matrix:
        console.print("  ".join(f"{v:+.5f}" for v in row))
    console.print(f"fit ΔE00 on {training}: mean {fit.delta_e00_mean:.3f}, max {fit.delta_e00_max:.3f}")


def register(app: typer.Typer) -> None:
    app.add_typer(illuminants_app, name="illuminants")
    from illumix.cmd_sensor_estimate import estimate

    sensors_app.command("estimate")(estimate)
    app.add_typer(sensors_app, name="sensors")
    app.command("whitepoint")(whitepoint)
    app.command("ccm")(ccm)
