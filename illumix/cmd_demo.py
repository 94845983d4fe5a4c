"""``illumix demo`` — render the demo room into a local store (if needed), serve it on 127.0.0.1,
fetch samples for two illuminant pairs over HTTP, save PNGs, print how to get more, keep serving."""

from __future__ import annotations

import io
import json
import os
import socket
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from illumix.consoles import make_console
from illumix.errors import UserError

if TYPE_CHECKING:  # numpy is imported where it is used: `--help` must not wait for it
    import numpy as np

console = make_console(stderr=True)
PAIRS = (("A", "D65"), ("FL11", "daylight:5500"))
DEMO_SENSOR = "Nikon 5100 (NPL)"


def _free_port(preferred: int) -> int:
    for port in (preferred, 0):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
                return s.getsockname()[1]
            except OSError:
                continue
    raise UserError("no free port on 127.0.0.1")


def _write_png(path: Path, rgb: np.ndarray) -> None:
    """Atomic 8-bit PNG of an ``(H, W, 3)`` image in [0, 1]."""
    import cv2
    import numpy as np

    ok, data = cv2.imencode(".png", np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8)[..., ::-1])
    if not ok:
        raise UserError(f"could not encode {path}")
    tmp = path.with_suffix(".png.tmp")
    tmp.write_bytes(data.tobytes())
    os.replace(tmp, path)


def _ensure_rendered(store: str, resolution: str, spp: int, workers: int) -> None:
    from illumix.cmd_render import render
    from illumix.renderer_jobs.render_settings import RenderSettings
    from illumix.retarget.denoise_methods import DEFAULT_METHOD

    d = RenderSettings()  # the renderer's defaults
    render(config=None, rules=None, store=store, demo=True, demo_seed=0, resolution=resolution, spp=spp, seed=0,
           wavelengths=d.wavelengths, sampler=d.sampler, bands_per_path=d.bands_per_path, views=None,
           groups=None, workers=workers, executor="local", address=None, skip_dark=True, adaptive=d.adaptive,
           noise_target=None, clean_max_spp=None, guide_paths=d.guide_paths, light_paths=d.light_paths,
           illumination=True,
           denoise=DEFAULT_METHOD, backend="mitsuba", boost_factor=None, boost_reach=None, overwrite=False,
           dry_run=False, as_json=False)


def _save_samples(url: str, out: Path) -> list[str]:
    import httpx
    import numpy as np

    from illumix.retarget.isp import preview

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create --out {out}: {exc.strerror}; give a writable directory") from None
    scenes = httpx.get(f"{url}/scenes", timeout=60).json()["scenes"]
    scene = next(s for s in scenes if s["name"].startswith("demo"))
    written = []
    for view in scene["views"]:
        for a, b in PAIRS:
            r = httpx.get(f"{url}/sample", timeout=300, params={
                "scene": scene["name"], "view": view["name"], "sensor": DEMO_SENSOR, "pair": f"{a},{b}",
                "outputs": "raw,gain,srgb,meta"})
            if r.status_code != 200:
                raise UserError(f"the service answered {r.status_code}: {r.json().get('detail')}")
            z = np.load(io.BytesIO(r.content))
            meta = json.loads(str(z["meta"]))
            stem = f"{scene['name']}_{view['name']}_{_lit_label(meta)}"
            raw = z["raw"]
            _write_png(out / f"{stem}_raw.png", preview(raw, 0.5 / max(float(np.percentile(raw, 99)), 1e-12)))
            gain = z["gain"]
            _write_png(out / f"{stem}_gain.png", gain / float(gain.max()))
            _write_png(out / f"{stem}_srgb.png", z["srgb"])
            (out / f"{stem}_meta.json").write_text(json.dumps(meta, indent=1))
            written += [f"{stem}_{k}.png" for k in ("raw", "gain", "srgb")]
            console.print(f"  {view['name']} pair={a},{b}: {_legend(meta)}  → {stem}_*.png",
                          soft_wrap=True, markup=False)
            console.print("    white points " + ", ".join(f"{i['illuminant']} R/G {i['white_point_rgb'][0]:.3f} "
                                                          f"B/G {i['white_point_rgb'][2]:.3f}"
                                                          for i in _lit(meta)), soft_wrap=True, markup=False)
    return written


def _lit(meta: dict) -> list[dict]:
    """``meta["illuminants"]`` entries of the groups that are lit (an illuminant, intensity > 0)."""
    return [i for i in meta["illuminants"] if i["illuminant"] and i["intensity"] > 0]


def _lit_label(meta: dict) -> str:
    """File-name part naming each lit group's illuminant: ``daylight-D65_ceiling-A_desk-A``."""
    def safe(text: str) -> str:
        return "".join(c if c.isalnum() or c in ".+-" else "" for c in text.replace(" ", "-"))
    return "_".join(f"{safe(i['group'])}-{safe(i['illuminant'])}" for i in _lit(meta)) or "unlit"


def _legend(meta: dict) -> str:
    """Which group got which light, and by what rule: ``daylight (daylight) ← D65, ceiling (artificial)
    ← A, desk (artificial) ← A [rule: kind]``."""
    rule = meta.get("lighting_rule") or {}
    kinds = {g["group"]: g["kind"] for g in rule.get("groups", [])}
    parts = []
    for i in meta["illuminants"]:
        kind = f" ({kinds[i['group']]})" if kinds.get(i["group"]) else ""
        light = i["illuminant"] if i["illuminant"] and i["intensity"] > 0 else "off"
        parts.append(f"{i['group']}{kind} ← {light}")
    return ", ".join(parts) + f" [rule: {rule.get('rule', 'order')}]"


def demo(
    store: str = typer.Option("./illumix-store", "--store", help="Where the demo cubes live."),
    out: Path = typer.Option(Path("./illumix-demo"), "--out", help="Where sample PNGs are written."),
    resolution: str = typer.Option("240x180", "--resolution", help="Render resolution WIDTHxHEIGHT."),
    spp: int = typer.Option(32, "--spp", min=16, help="Render paths per pixel."),
    workers: int = typer.Option(1, "--workers", min=1, help="Render worker processes."),
    port: int = typer.Option(8000, "--port", min=0, max=65535, help="Port on 127.0.0.1 (a free one if taken)."),
    serve: bool = typer.Option(True, "--serve/--no-serve", help="Keep serving after the samples."),
) -> None:
    """Render the demo room (if needed), serve it on 127.0.0.1, fetch and save samples."""
    import uvicorn

    from illumix.allocator import tune_for_service
    from illumix.cmd_serve import open_store
    from illumix.service.app import create_app

    if out.exists() and not out.is_dir():  # found now, not after the render and the server start
        raise UserError(f"--out {out} is a file; give a directory for the sample PNGs")
    console.rule("[bold]1. render the demo room (skipped where the store is complete)")
    _ensure_rendered(store, resolution, spp, workers)
    console.rule("[bold]2. serve")
    port = _free_port(port)
    tune_for_service()
    app = create_app(open_store(store), cache_mb=512)  # step 1 made it
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        if not thread.is_alive():
            raise UserError(f"the service could not start on 127.0.0.1:{port}")
        time.sleep(0.05)
    url = f"http://127.0.0.1:{port}"
    console.print(f"serving {store} at {url} (OpenAPI docs: {url}/docs)")
    try:
        console.rule(f"[bold]3. fetch samples ({DEMO_SENSOR})")
        written = _save_samples(url, out)
        console.print(f"wrote {len(written)} PNGs into {out}/ (raw preview, gain map, sRGB)")
        console.rule("[bold]4. get more")
        if not serve:  # the server stops with this command: point at one that stays
            print(f"illumix serve --store {store}   # then fetch samples as shown in the README")
            return
        print(f"curl -o sample.npz '{url}/sample?sensor=XYZ&pair=A,D65'")
        print(f"curl -o srgb.png '{url}/sample?pair=FL11,D50&outputs=srgb&format=png'")
        print("python -c \"import httpx, numpy as np, io; "
              f"z = np.load(io.BytesIO(httpx.get('{url}/sample', params={{'pair': 'A,D65'}}).content)); "
              "print({k: z[k].shape for k in z.files})\"")
        if serve:
            console.print("serving until Ctrl-C …")
            while thread.is_alive():
                thread.join(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        server.should_exit = True
        thread.join(timeout=10)


def register(app: typer.Typer) -> None:
    app.command("demo")(demo)
