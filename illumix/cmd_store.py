"""``illumix store info PATH [--json]`` and ``illumix store verify PATH [--json]``."""

from __future__ import annotations

import json

import typer
from rich.table import Table

from illumix.consoles import make_console
from illumix.errors import UserError

console = make_console()
store_app = typer.Typer(help="Inspect and check a cube store.", no_args_is_help=True)

PATH_HELP = "Store directory or fsspec URL (e.g. ./illumix-store, s3://bucket/store)."


def _open(path: str, writable: bool = False):
    from illumix.store import CubeStore, StoreError

    try:
        if writable and not CubeStore.exists(path):
            return CubeStore.open(path, mode="r")  # "no store here", in the read-only wording
        return CubeStore.open(path, mode="a" if writable else "r")
    except StoreError as exc:
        raise UserError(str(exc)) from None


def _has_root_document(path: str) -> bool:
    from illumix.store.backend import Backend

    try:
        return Backend(path, read_only=True).exists("zarr.json")
    except Exception:  # noqa: BLE001 - an unreachable location: not a damaged store
        return False


def _size(n: int | None) -> str:
    """Bytes as B / KiB / MiB / GiB."""
    if n is None:
        return ""
    for unit in ("B", "KiB", "MiB"):
        if n < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.2f} GiB"


@store_app.command("info")
def info(path: str = typer.Argument(..., help=PATH_HELP),
         as_json: bool = typer.Option(False, "--json", help="Print JSON: {scenes: [{name, views: [{name, "
                                      "width, height, groups: [{name, emission, dtype, complete}]}]}]}.")) -> None:
    """List scenes, views, light groups, shapes, dtypes, sizes and completeness."""
    from illumix.store import StoreError
    from illumix.store.report import info as store_info

    st = _open(path)
    try:
        rep = store_info(st)
    except StoreError as exc:
        raise UserError(str(exc)) from None
    if as_json:
        print(json.dumps(rep))
        return
    table = Table("scene", "view", "size", "group", "emission", "dtype", "illumination", "complete", "on disk",
                  title=f"illumix store {rep['store']}")
    for s in rep["scenes"]:
        for v in s["views"]:
            size = f"{v['width']}x{v['height']}" if v["width"] else "[red]?[/]"
            if not v["groups"]:
                table.add_row(s["name"], v["name"], size, "[dim](no groups)[/]", "", "", "", "", "")
            for g in v["groups"]:
                done = "yes" if g["complete"] else "[yellow]no[/]"
                dtype = "empty" if g.get("empty") else (g["dtype"] or "")
                illum = "yes" if g.get("illumination") else ("" if g.get("empty") else "[yellow]no[/]")
                table.add_row(s["name"], v["name"], size, g["name"], g["emission"] or "", dtype, illum, done,
                              _size(g.get("bytes")))
    console.print(table)
    cubes = [g for s in rep["scenes"] for v in s["views"] for g in v["groups"] if g["complete"] and not g.get("empty")]
    methods = sorted({g["denoised"] for g in cubes if g.get("denoised")})
    n_dn = sum(bool(g.get("denoised")) for g in cubes)
    console.print(f"denoised copies: {', '.join(methods) or 'none'} ({n_dn} of {len(cubes)} cubes)")
    regs = ", ".join(f"{k}: {len(v)}" for k, v in rep["registries"].items())
    console.print(f"registries — {regs}; pending writes: {rep['pending_writes']}")


@store_app.command("verify")
def verify(path: str = typer.Argument(..., help=PATH_HELP),
           as_json: bool = typer.Option(False, "--json", help="Print the report as JSON."),
           repair: bool = typer.Option(False, "--repair", help="First remove what interrupted writes left: "
                                       "orphaned .partial files, staged writes of dead writers, replaced "
                                       "nodes in _trash (printed). Damaged data is only reported, never removed."),
           min_age: float | None = typer.Option(None, "--min-age", min=0, help="--repair: also remove leftovers of "
                                                "unknown writers older than this many seconds (default 600).")) -> None:
    """Check every byte: each file against its node's checksums (SHA-256 manifests, CRC-32C per
    chunk), every array and all metadata (schema, shapes, chunks, finiteness, statistics).

    Exit code 0 when the store is sound, 1 when any problem is found (each printed with where)."""
    from illumix.store import StoreError
    from illumix.store.report import verify as store_verify

    if min_age is not None and not repair:
        raise UserError("--min-age goes with --repair (it says which leftovers --repair may remove)")
    try:
        st = _open(path, writable=repair)
    except UserError as exc:
        if not _has_root_document(path):
            raise
        # the store is there but its root document is damaged: a problem found, not a usage error
        console.print(f"[red]PROBLEM[/] zarr.json: {exc}", soft_wrap=True, highlight=False)
        raise typer.Exit(1) from None
    try:
        rep = store_verify(st, repair=repair, min_age_s=600.0 if min_age is None else min_age)
    except StoreError as exc:
        raise UserError(str(exc)) from None
    if as_json:
        print(json.dumps(rep))
    else:
        for p in rep["problems"]:
            console.print(f"[red]PROBLEM[/] {p['where']}: {p['what']}", soft_wrap=True, highlight=False)
        for n in rep["notes"]:
            console.print(f"[yellow]note[/] {n['where']}: {n['what']}", soft_wrap=True, highlight=False)
        for r in rep["repaired"]:
            console.print(f"[cyan]removed[/] {r}", soft_wrap=True, highlight=False)
        c = rep["checked"]
        status = "[green]OK[/]" if rep["ok"] else f"[red]{len(rep['problems'])} problem(s)[/]"
        console.print(f"{status}: checked {c['views']} views, {c['aovs']} AOVs, {c['cubes']} cubes, "
                      f"{c['registry_entries']} registry entries, {c['files_checksummed']} files against their "
                      f"checksums in {rep['store']}", soft_wrap=True, highlight=False)
    if not rep["ok"]:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    app.add_typer(store_app, name="store")
