"""Quick looks at a scene before spending hours on it: low-spp sRGB previews of its views and a
contact sheet of many scenes.

A preview is Mitsuba's own spectral path tracer (``path``, depth ≤ 5) with every light group on at
the emission the scene gives it (not the relit cube — no sensor, no illuminant choice), written to
linear sRGB by Mitsuba's spectral variant, auto-exposed so the 97th percentile of luminance sits at
0.9, then sRGB-encoded. Portals (window skies) render in a pass of their own, as in the real render
(:func:`renderer_jobs.mitsuba.render.emitter_passes`). Good enough to see layout, materials and
which lights dominate; not data.
"""

from __future__ import annotations

import numpy as np

PREVIEW_RES = (160, 120)
PREVIEW_SPP = 16


def preview_linear(scene, views: list[str] | None = None, resolution=PREVIEW_RES, spp: int = PREVIEW_SPP,
                   seed: int = 0) -> np.ndarray:
    """``(V, H, W, 3)`` float32 linear sRGB of each view with every group on."""
    from illumix.renderer_jobs.mitsuba.render import emitter_passes
    from illumix.renderer_jobs.mitsuba.scene_dict import batch_sensor_dict, build_scene_dict, load_padded
    from illumix.renderer_jobs.mitsuba.variant import import_mitsuba

    mi, _ = import_mitsuba()
    views = [v.name for v in scene.views] if views is None else views
    out = np.zeros((len(views), resolution[1], resolution[0], 3), np.float32)
    for portals in emitter_passes(scene, scene.group_names):
        doc = build_scene_dict(scene, views[0], None, resolution=resolution, portals=portals)
        doc["integrator"] = {"type": "path", "max_depth": min(scene.max_depth, 5)}
        doc["sensor"] = batch_sensor_dict(mi, scene, views, resolution, spp)  # all views, one render
        rgb = np.asarray(mi.render(load_padded(mi, doc), spp=spp, seed=seed), np.float32)[..., :3]
        out += np.stack(np.split(rgb, len(views), axis=1))
    return out


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Auto-exposed (97th percentile of luminance → 0.9) 8-bit sRGB of a linear ``(H, W, 3)`` image."""
    y = linear @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    p = float(np.percentile(y, 97)) if np.any(y > 0) else 1.0
    from illumix.retarget.isp import encode_srgb

    return (encode_srgb(linear * (0.9 / max(p, 1e-12))) * 255 + 0.5).astype(np.uint8)


def contact_sheet(tiles: list[tuple[str, np.ndarray]], columns: int = 4) -> np.ndarray:
    """One ``(H, W, 3)`` uint8 image of labelled ``(label, tile)`` pairs (tiles: uint8 sRGB, any size:
    each is fitted into the first tile's size)."""
    import cv2

    if not tiles:
        raise ValueError("a contact sheet needs at least one tile")
    h, w = tiles[0][1].shape[:2]
    label_h = 16
    rows = (len(tiles) + columns - 1) // columns
    sheet = np.full((rows * (h + label_h), min(columns, len(tiles)) * w, 3), 32, np.uint8)
    for k, (label, tile) in enumerate(tiles):
        r, c = divmod(k, columns)
        y0, x0 = r * (h + label_h), c * w
        sheet[y0 + label_h:y0 + label_h + h, x0:x0 + w] = cv2.resize(tile, (w, h), interpolation=cv2.INTER_AREA)
        cv2.putText(sheet, label[: max(4, w // 7)], (x0 + 3, y0 + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.38,
                    (230, 230, 230), 1, cv2.LINE_AA)
    return sheet
