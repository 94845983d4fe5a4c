"""``GET /``: the web explorer, a static page (``service/web_static/``) that only talks to this service.

Plain HTML, CSS and ES modules with no build step; the one library, uPlot (MIT), is vendored under
``web_static/vendor/`` (version and licence in ``web_static/vendor/VENDOR.md``), so the page makes no
request beyond the service. Its assets are served under ``/web/`` by Starlette's ``StaticFiles``.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, FastAPI
from fastapi.responses import FileResponse, Response
from fastapi.staticfiles import StaticFiles

STATIC = Path(__file__).resolve().parents[1] / "web_static"
router = APIRouter(tags=["web"])


# response_class=Response, as for /metrics: HTMLResponse would document the app-wide JSON error answers
# (405) as text/html too. The 200 is documented here and answered as HTML.
@router.get("/", response_class=Response,
            responses={200: {"content": {"text/html": {"schema": {"type": "string"}}},
                             "description": "the web explorer page"}})
def index() -> FileResponse:
    """The web explorer: pick a scene, lights and sensor, and look at the raw, the ground truth, the
    single-white-point baseline, the gain and mixture maps, spectra and white points."""
    # no-cache: the page and its modules change with the service; revalidation is cheap on loopback
    return FileResponse(STATIC / "index.html", media_type="text/html", headers={"Cache-Control": "no-cache"})


def mount_static(app: FastAPI) -> None:
    """Serve ``web_static/`` under ``/web`` (the page's scripts, styles and vendored library)."""
    app.mount("/web", StaticFiles(directory=STATIC), name="web")
