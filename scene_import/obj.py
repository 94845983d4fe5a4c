"""Wavefront OBJ + MTL → an illumix scene document.

The OBJ is parsed here (positions, ``vt``, ``vn``, polygons fan-triangulated, negative indices,
``o``/``g`` objects, ``usemtl``, ``mtllib``), so every face keeps its material exactly; one PLY is
written per (object, material) pair, in the file's own coordinates (OBJ has no unit: metres and
+y up are assumed, as illumix). ``vt`` has v up, Mitsuba's bitmaps v down: v is flipped.
Files are found as exporters write them (:func:`find_file`): ``mtllib`` relative to the OBJ's folder,
``map_Kd``/``map_Ke`` relative to their MTL's folder (then the OBJ's); Windows paths and case accepted.

MTL mapping: ``Kd`` (linear RGB) → a Jakob–Hanika spectrum; ``map_Kd`` → a bitmap texture (PNG written
beside the scene, ``Kd`` baked in); ``Ks`` > 0 → ``roughplastic`` with ``α = Pr²`` (PBR extension) or
``α = √(2 / (Ns + 2))`` (the Phong exponent's Beckmann equivalent, Walter et al. 2007), else
``diffuse``; ``Pm ≥ 0.5`` → ``roughconductor`` (a mirror tinted by ``Kd``). ``Ke`` (radiance,
linear RGB) makes the material's shapes area lights; their group's illuminant follows ``Ke``'s
colour temperature. Transparency (``d``, ``Tr``), other maps (bump, normal, specular…) and
unknown statements are warnings naming the material; ``map_Ke`` is averaged into ``Ke``. OBJ has no
cameras: a default view framing the bounding box is added, with a warning.
"""

from __future__ import annotations

import shlex
from pathlib import Path, PureWindowsPath

import numpy as np

from illumix.scene.spectra import SceneError
from illumix.scene_import.builder import SceneBuilder
from illumix.scene_import.colour_match import mean_rgb, reflectance, rgb_light, write_texture

KNOWN_MTL = {"newmtl", "kd", "ka", "ks", "ke", "ns", "ni", "d", "tr", "illum", "map_kd", "map_ke", "pr", "pm", "tf"}
DIR = "__dir"  # a material's entry: the folder of its MTL file (its maps are relative to it)


def find_file(name: str, folders: list[Path]) -> Path | None:
    """A file an OBJ/MTL names, as exporters write them: relative to ``folders`` in order (the naming
    file's own folder first), Windows ``\\`` separators and absolute paths from another machine
    (then its base name) accepted, and the name's case ignored when nothing matches exactly."""
    name = name.strip().strip('"')
    if not name:
        return None
    win = PureWindowsPath(name)
    rel = Path(*win.parts) if "\\" in name else Path(name)
    tries = [rel] if not rel.is_absolute() and not win.drive else [rel, Path(win.name)]
    for folder in folders:
        for t in tries:
            p = t if t.is_absolute() else folder / t
            if p.is_file():
                return p
            if p.parent.is_dir():
                low = p.name.lower()
                hit = next((q for q in p.parent.iterdir() if q.name.lower() == low and q.is_file()), None)
                if hit is not None:
                    return hit
    return None


def _floats(parts: list[str], n: int, default: float = 0.0) -> list[float]:
    vals = [float(x) for x in parts[:n]]
    return vals + [vals[-1] if vals else default] * (n - len(vals))


def parse_mtl(path: Path, warn) -> dict[str, dict]:
    """``{material name: {statement (lower case): arguments}}``."""
    mats: dict[str, dict] = {}
    cur: dict | None = None
    if not path.is_file():
        warn(f"{path.name}: material library does not exist; its materials are grey")
        return mats
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        key = parts[0].lower()
        if key == "newmtl":
            cur = mats.setdefault(" ".join(parts[1:]) or "unnamed", {DIR: [str(path.parent)]})
        elif cur is not None:
            cur[key] = parts[1:]
    return mats


def parse_obj(path: Path, warn):
    """``(positions (n, 3), uvs (k, 2), normals (m, 3), groups, mtllib lines)``; ``groups`` maps
    ``(object, material)`` to a list of triangles of corner triples ``(v, vt, vn)`` (0-based, −1 absent)."""
    v: list[list[float]] = []
    vt: list[list[float]] = []
    vn: list[list[float]] = []
    groups: dict[tuple[str, str | None], list] = {}
    libs: list[str] = []
    obj, mat = "default", None
    skipped: set[str] = set()
    for ln, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
        parts = line.split("#", 1)[0].split()
        if not parts:
            continue
        k = parts[0]
        try:
            if k == "v":
                v.append(_floats(parts[1:], 3))
            elif k == "vt":
                vt.append(_floats(parts[1:], 2))
            elif k == "vn":
                vn.append(_floats(parts[1:], 3))
            elif k == "f":
                corners = []
                for c in parts[1:]:
                    ids = (c.split("/") + ["", ""])[:3]
                    out = []
                    for s, n in zip(ids, (len(v), len(vt), len(vn)), strict=True):
                        if s == "":
                            out.append(-1)
                            continue
                        j = int(s)
                        j = j - 1 if j > 0 else n + j
                        if not 0 <= j < n:
                            raise ValueError(f"index {s} out of range")
                        out.append(j)
                    corners.append(tuple(out))
                if len(corners) >= 3:
                    tris = groups.setdefault((obj, mat), [])
                    tris.extend((corners[0], corners[i], corners[i + 1]) for i in range(1, len(corners) - 1))
            elif k in ("o", "g"):
                if len(parts) > 1:
                    obj = " ".join(parts[1:])
            elif k == "usemtl":
                mat = " ".join(parts[1:]) or None
            elif k == "mtllib":
                libs.append(line.split("#", 1)[0].strip()[len("mtllib"):].strip())
            elif k in ("s", "vp"):
                pass
            else:
                skipped.add(k)
        except ValueError as exc:
            raise SceneError(f"{path}:{ln}: bad {k!r} statement ({exc})") from None
    for k in sorted(skipped):
        warn(f"{path.name}: OBJ statement {k!r} (lines, curves, …) is not supported; ignored")
    return np.asarray(v, float).reshape(-1, 3), np.asarray(vt, float).reshape(-1, 2), \
        np.asarray(vn, float).reshape(-1, 3), groups, libs


MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
               "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}  # MTL map options → max args


def _map(m: dict, key: str, folders: list[Path], what: str, warn):
    """The PIL image of a material's ``map_*`` statement (options skipped with a warning), found
    relative to the MTL's folder first (:func:`find_file`); None when absent or unreadable."""
    if key not in m:
        return None
    args, names, opts, i = m[key], [], [], 0
    while i < len(args):
        a = args[i]
        if a.lower() in MAP_OPTIONS and not names:
            n = MAP_OPTIONS[a.lower()]
            j = i + 1
            while j < len(args) and j <= i + n and (n == 1 or _is_number(args[j])):
                j += 1
            opts.append(" ".join(args[i:j]))
            i = j
        else:
            names.append(a)
            i += 1
    label = key.replace("map_k", "map_K")
    if opts:
        warn(f"{what}: {label} options {' '.join(opts)} are ignored")
    tex = find_file(" ".join(names), folders)
    if tex is None:
        warn(f"{what}: {label} {' '.join(names)!r} not found (looked in {', '.join(map(str, folders))}); "
             f"{'Kd' if key == 'map_kd' else 'Ke'} is used")
        return None
    try:
        from PIL import Image

        img = Image.open(tex)
        img.load()
        return img
    except (OSError, ValueError) as exc:
        warn(f"{what}: {label} {tex.name!r} cannot be read ({exc}); {'Kd' if key == 'map_kd' else 'Ke'} is used")
        return None


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _material(b: SceneBuilder, obj_dir: Path, name: str, m: dict) -> tuple[str, tuple | None]:
    what = f"material {name!r}"
    warn = b.warn
    folders = list(dict.fromkeys([Path(m.get(DIR, [str(obj_dir)])[0]), obj_dir]))
    for k in sorted(set(m) - KNOWN_MTL - {DIR}):
        warn(f"{what}: MTL statement {k!r} is not supported; ignored")
    kd = np.asarray(_floats(m.get("kd", ["0.8"]), 3), float)
    ks = np.asarray(_floats(m.get("ks", ["0"]), 3), float)
    d = float(m.get("d", ["1"])[0]) if "d" in m else 1.0 - float(m.get("tr", ["0"])[0])
    if d < 1:
        warn(f"{what}: transparency (d {d:g}) is ignored; the surface is opaque")
    if "pr" in m:
        alpha = float(m["pr"][0]) ** 2
    else:
        alpha = float(np.sqrt(2.0 / (max(float(m.get("ns", ["0"])[0]), 0.0) + 2.0)))  # Ns < 0: as 0
    alpha = min(max(alpha, 1e-3), 1.0)
    metal = float(m.get("pm", ["0"])[0]) >= 0.5
    plastic = not metal and ks.max() > 0 and alpha < 0.999
    scale = 1.0
    if plastic:
        from illumix.scene.plastic_scale import plastic_diffuse_scale

        scale = plastic_diffuse_scale(alpha, 1.5)
        if np.ptp(ks) > 1e-6:
            warn(f"{what}: coloured Ks {ks.tolist()} is not kept; the specular layer is a clear coat (IOR 1.5)")
    refl = None
    img = _map(m, "map_kd", folders, what, warn)
    if img is not None:
        if metal:
            kd = kd * mean_rgb(np.asarray(img.convert("RGB")))
            warn(f"{what}: a metal's map_Kd is averaged to one colour")
        else:
            path, rel = b.file_path(f"{name}-Kd", ".png")
            write_texture(img, np.minimum(kd / scale, 1.0), path)
            refl = {"file": rel}
    if refl is None:
        refl = reflectance(np.minimum(kd / scale, 1.0), what, warn)
    if metal:
        doc = {"kind": "roughconductor", "conductor": "none", "alpha": alpha, "specular_reflectance": reflectance(kd, what, warn)}
    elif plastic:
        doc = {"kind": "roughplastic", "reflectance": refl, "alpha": alpha, "int_ior": 1.5}
    else:
        doc = {"kind": "diffuse", "reflectance": refl}
    ke = np.asarray(_floats(m.get("ke", ["1" if "map_ke" in m else "0"]), 3), float)
    img = _map(m, "map_ke", folders, what, warn) if ke.max() > 0 else None
    if img is not None:  # illumix area lights are uniform: the map's mean colour
        ke = ke * mean_rgb(np.asarray(img.convert("RGB")))
        warn(f"{what}: map_Ke (emission texture) is averaged to one colour, radiance {np.round(ke, 4).tolist()}")
    emission = None
    if ke.max() > 0:
        xy, y = rgb_light(ke)
        emission = (xy, y)
    return b.add_material(name, doc), emission


def _libraries(line: str, folder: Path, warn) -> list[Path]:
    """The MTL files of one ``mtllib`` line, relative to the OBJ's folder: the whole line as one name
    (exporters write names with spaces unquoted), else its (possibly quoted) names one by one."""
    whole = find_file(line, [folder])
    if whole is not None:
        return [whole]
    out = []
    for name in shlex.split(line, posix=False):
        p = find_file(name, [folder])
        if p is None:
            warn(f"mtllib {name!r}: no such file beside the OBJ (in {folder}); its materials are grey")
        else:
            out.append(p)
    return out


def import_obj(path: Path, b: SceneBuilder) -> str:
    """Fill ``b`` from an OBJ file (and its MTL libraries); returns the scene's name."""
    v, vt, vn, groups, libs = parse_obj(path, b.warn)
    if not groups:
        raise SceneError(f"{path}: the OBJ file has no faces")
    mtl: dict[str, dict] = {}
    for line in libs:
        for lib in _libraries(line, path.parent, b.warn):
            mtl.update(parse_mtl(lib, b.warn))
    made: dict[str | None, tuple[str, tuple | None]] = {}
    multi = {o for o, _ in groups if sum(1 for o2, _ in groups if o2 == o) > 1}
    for (obj, mat), tris in groups.items():
        if mat not in made:
            if mat is None or mat not in mtl:
                if mat is not None:
                    b.warn(f"material {mat!r}: not in the MTL file(s); grey diffuse 0.8 used")
                made[mat] = (b.add_material(mat or "default", {"kind": "diffuse", "reflectance": {"value": 0.8}}), None)
            else:
                made[mat] = _material(b, path.parent, mat, mtl[mat])
        key, emission = made[mat]
        corners = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
        uniq, inverse = np.unique(corners, axis=0, return_inverse=True)
        faces = inverse.reshape(-1, 3)
        pos = v[uniq[:, 0]]
        has_uv = bool(np.all(uniq[:, 1] >= 0)) and len(vt) > 0
        has_n = bool(np.all(uniq[:, 2] >= 0)) and len(vn) > 0
        uv = np.c_[vt[uniq[:, 1], 0], 1.0 - vt[uniq[:, 1], 1]] if has_uv else None  # OBJ v up → bitmap v down
        name = f"{obj}-{mat}" if obj in multi else obj
        rel = b.write_ply(name, pos, faces, vn[uniq[:, 2]] if has_n else None, uv)
        b.extend_bounds(pos)
        em = None
        if emission is not None:
            xy, y = emission
            em = ([mat or "", obj], mat or obj, xy, y)
        b.add_shape(name, {"type": "ply", "filename": rel, "face_normals": not has_n, "material": key}, em,
                    what=f"object {obj!r} (material {mat!r})")
    b.default_view(f"{path.name}: OBJ files have no cameras")
    return path.stem
