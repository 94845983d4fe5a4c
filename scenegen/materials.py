"""Materials by class: measured reflectances chosen by what the thing is made of.

Every class draws from measured sets (:mod:`retarget.reflectances`: Vrhel objects, nature, food and
clothes, DuPont paints, Munsell, the Gretag SG chart, CIE 2017 TCS, ColorChecker) filtered by the
colour the class should have — CIELAB lightness, chroma and hue under D65 (e.g. wood: hue 35–85°,
L* 25–75) — and gives the class its surface: diffuse paint and paper, rough plastic for ceramic,
plastic and leather (GGX alpha by class), rough conductors for metal, glass as a dielectric, and
**spectral textures** (:class:`scene.textures.PatternTexture`) where real surfaces
have them: wood grain mixing two woods, woven fabric and rugs mixing two or three cloths, book
covers in stripes, pictures mixing five to six spectra, floor tiles.

:class:`Materials` is the :class:`scenegen.parts.MaterialPicker` a room is built with: ``pick(cls)``
hands out a material name, reusing one already made for the class with probability
:data:`REUSE` (rooms repeat materials: chairs of one set, one wall paint), and ``docs`` holds the
scene's ``materials`` section.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from illumix.retarget.errors import unknown_name

REUSE = 0.5  # probability that pick() reuses a material already made for the class


@dataclass(frozen=True)
class Pool:
    """Which spectra a class draws from: sets, and CIELAB ranges (L*, C*, hue angle in degrees)."""

    sets: tuple[str, ...]
    lightness: tuple[float, float] = (0, 100)
    chroma: tuple[float, float] = (0, 200)
    hue: tuple[float, float] | None = None  # degrees; lo > hi wraps through 0


OBJECTS = ("Vrhel Objects", "DuPont Paint", "Munsell Vrhel", "Gretag SG", "CIE 2017")
POOLS: dict[str, Pool] = {
    "wood": Pool(("Vrhel Objects", "Vrhel Nature", "CIE 2017"), (25, 75), (8, 50), (35, 85)),
    "paint": Pool(("DuPont Paint", "Munsell Vrhel", "CIE 2017"), (68, 96), (0, 22)),
    "accent": Pool(("DuPont Paint", "Munsell Vrhel"), (40, 85), (15, 70)),
    "ceiling": Pool(("DuPont Paint", "Gretag SG"), (85, 100), (0, 6)),
    "fabric": Pool(("Vrhel Clothes", "DuPont Paint", "Munsell Vrhel"), (20, 85), (0, 70)),
    "linen": Pool(("Vrhel Clothes", "DuPont Paint"), (70, 97), (0, 18)),
    "plant": Pool(("Vrhel Nature",), (20, 65), (10, 80), (95, 170)),
    "ceramic": Pool(("DuPont Paint", "Munsell Vrhel", "Gretag SG"), (30, 97), (0, 60)),
    "paper": Pool(("Vrhel Objects", "Gretag SG", "DuPont Paint"), (82, 100), (0, 10)),
    "book": Pool(("DuPont Paint", "Vrhel Clothes", "Munsell Vrhel", "Gretag SG"), (15, 85), (5, 80)),
    "plastic": Pool(("DuPont Paint", "Gretag SG", "CIE 2017"), (20, 95), (0, 80)),
    "rug": Pool(("Vrhel Clothes", "Munsell Vrhel"), (15, 80), (5, 60)),
    "picture": Pool(("Vrhel Nature", "Vrhel Food", "Vrhel Objects", "ColorChecker N Ohta"), (10, 95), (0, 120)),
    "leather": Pool(("Vrhel Objects", "Vrhel Clothes"), (15, 55), (10, 50), (20, 75)),
    "soil": Pool(("Vrhel Nature", "Vrhel Objects"), (10, 40), (3, 40), (20, 90)),
    "food": Pool(("Vrhel Food",)),
    "floor": Pool(("Vrhel Objects", "CIE 2017", "DuPont Paint"), (25, 70), (3, 40), (30, 90)),
    "tile": Pool(("DuPont Paint", "Munsell Vrhel", "Gretag SG"), (35, 95), (0, 35)),
}
# Classes that are not drawn from a pool.
FIXED = ("metal", "glass", "screen_frame", "black", "lampshade", "white")
CLASSES = tuple(POOLS) + FIXED
CONDUCTORS = ("Al", "Al", "Cr", "Cu", "Au", "Ag", "Ni_palik")


@cache
def _lab_table(set_name: str) -> np.ndarray:
    """CIELAB ``(n, 3)`` of a set's reflectances under D65 (CIE 1931 2°), on illumix's grid."""
    import colour

    from illumix.retarget.grid import DEFAULT_GRID
    from illumix.retarget.reflectances import get_reflectances

    _, r = get_reflectances(set_name)
    wl = DEFAULT_GRID.wavelengths
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz_bar = np.stack([np.interp(wl, cmfs.wavelengths, cmfs.values[:, i]) for i in range(3)], axis=1)
    d65 = np.interp(wl, colour.SDS_ILLUMINANTS["D65"].wavelengths, colour.SDS_ILLUMINANTS["D65"].values)
    k = 1 / (d65 @ xyz_bar[:, 1])
    xyz = (r * d65) @ xyz_bar * k
    white = d65 @ xyz_bar * k
    return colour.XYZ_to_Lab(xyz, colour.XYZ_to_xy(white))


@cache
def candidates(cls: str) -> tuple[tuple[str, int], ...]:
    """``(set, index)`` of every spectrum in class ``cls``'s pool."""
    pool = POOLS[cls]
    out = []
    for s in pool.sets:
        lab = _lab_table(s)
        c = np.hypot(lab[:, 1], lab[:, 2])
        h = np.degrees(np.arctan2(lab[:, 2], lab[:, 1])) % 360
        ok = (lab[:, 0] >= pool.lightness[0]) & (lab[:, 0] <= pool.lightness[1])
        ok &= (c >= pool.chroma[0]) & (c <= pool.chroma[1])
        if pool.hue is not None:
            lo, hi = pool.hue
            ok &= ((h >= lo) & (h <= hi)) if lo <= hi else ((h >= lo) | (h <= hi))
        out += [(s, int(i)) for i in np.flatnonzero(ok)]
    if not out:
        raise ValueError(f"material class {cls!r}: no measured spectrum in its pool")
    return tuple(out)


def _lib(ref: tuple[str, int]) -> dict:
    return {"library": ref[0], "index": ref[1]}


class Materials:
    """The materials of one scene (see module docstring)."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng
        self.docs: dict[str, dict] = {}
        self.by_class: dict[str, list[str]] = {}

    def spectrum(self, cls: str) -> dict:
        """One spectrum spec drawn from ``cls``'s pool."""
        cands = candidates(cls)
        return _lib(cands[int(self.rng.integers(len(cands)))])

    def pick(self, cls: str) -> str:
        key = cls.lower()
        if key not in CLASSES:
            raise ValueError(unknown_name("material class", cls, list(CLASSES)))
        made = self.by_class.setdefault(key, [])
        if made and (key in FIXED or self.rng.random() < REUSE) and key not in ("book", "picture"):
            return made[int(self.rng.integers(len(made)))]
        name = f"{key}_{len(made)}"
        self.docs[name] = self._make(key)
        made.append(name)
        return name

    def _texture(self, pattern: str, spectra: list[dict], scale=(1.0, 1.0), resolution: int = 256,
                 **params) -> dict:
        return {"pattern": pattern, "spectra": spectra, "seed": int(self.rng.integers(2**31)),
                "scale": [round(float(scale[0]), 4), round(float(scale[1]), 4)], "resolution": int(resolution),
                "params": {k: round(float(v), 4) for k, v in params.items()}}

    def _wood(self) -> dict:
        """Wood grain at its physical size: ``rings`` grain lines per texture tile, the tile repeated
        ``scale`` times per metre so that the lines lie 4–14 mm apart (meshes' UVs are in metres)."""
        rings = float(self.rng.uniform(18, 30))
        spacing = float(self.rng.uniform(0.004, 0.014))  # m between grain lines
        s = 1 / (rings * spacing)
        return self._texture("wood", [self.spectrum("wood"), self.spectrum("wood")], (s, s * 0.5), 512,
                             rings=rings, noise=float(self.rng.uniform(0.25, 0.45)))

    def _cloth(self, cls: str) -> dict:
        """Cloth at its physical size (meshes' UVs in metres): a weave of 3–5 mm threads, stripes
        1.5–5 cm wide, checks of 2–8 cm; a rug's pattern spans the rug (its mesh's UVs are [0, 1])."""
        rng = self.rng
        spectra = [self.spectrum(cls) for _ in range(int(rng.integers(2, 4)))]
        if cls == "rug":
            pattern = str(rng.choice(["weave", "stripes", "blobs", "picture"]))
            extra = {"threads": 240.0} if pattern == "weave" else {}
            return self._texture(pattern, spectra, (1.0, 1.0), 1024 if pattern == "weave" else 512, **extra)
        pattern = str(rng.choice(["weave", "weave", "stripes", "checker"]))
        size = {"weave": 48 * rng.uniform(0.003, 0.005), "stripes": 12 * rng.uniform(0.015, 0.05),
                "checker": 8 * rng.uniform(0.02, 0.08)}[pattern]
        return self._texture(pattern, spectra, (1 / size, 1 / size), 512 if pattern == "weave" else 256)

    def _make(self, cls: str) -> dict:  # one branch per class
        rng = self.rng
        if cls == "metal":
            return {"kind": "roughconductor", "conductor": str(rng.choice(CONDUCTORS)),
                    "alpha": round(float(rng.uniform(0.05, 0.35)), 3)}
        if cls == "glass":
            return {"kind": "dielectric", "int_ior": 1.5}
        if cls in ("screen_frame", "black"):
            return {"kind": "roughplastic", "reflectance": {"value": round(float(rng.uniform(0.02, 0.05)), 3)},
                    "alpha": 0.2}
        if cls == "white":
            return {"kind": "diffuse", "reflectance": {"value": 0.8}}
        if cls == "lampshade":  # thin fabric or paper: pale, diffuse
            return {"kind": "diffuse", "reflectance": self.spectrum(str(rng.choice(["linen", "paper"])))}
        if cls == "wood":
            return {"kind": "roughplastic", "alpha": round(float(rng.uniform(0.15, 0.45)), 3), "reflectance": self._wood()}
        if cls == "floor":
            if rng.random() < 0.6:  # boards: wood grain (the floor mesh cuts each board from elsewhere)
                return {"kind": "roughplastic", "alpha": round(float(rng.uniform(0.2, 0.5)), 3), "reflectance": self._wood()}
            if rng.random() < 0.5:  # tiles 30–60 cm with grout
                s = 1 / (4 * float(rng.uniform(0.3, 0.6)))
                return {"kind": "roughplastic", "alpha": round(float(rng.uniform(0.05, 0.2)), 3),
                        "reflectance": self._texture("tiles", [self.spectrum("paint"), self.spectrum("tile"),
                                                               self.spectrum("tile")], (s, s), 512, grout=0.02)}
            return {"kind": "diffuse", "reflectance": self._texture(  # carpet: 4–6 mm loops
                "weave", [self.spectrum("rug"), self.spectrum("rug")], (4.0, 4.0), 512, threads=48)}
        if cls in ("fabric", "rug", "linen"):
            return {"kind": "diffuse", "reflectance": self._cloth(cls)}
        if cls == "book":  # covers and spines in bands of 3–6 cm
            spectra = [self.spectrum("book") for _ in range(2)] + [self.spectrum("paper")]
            return {"kind": "roughplastic", "alpha": 0.3, "reflectance": self._texture("stripes", spectra, (6.0, 6.0),
                                                                                      stripes=3)}
        if cls == "picture":
            spectra = [self.spectrum("picture") for _ in range(int(rng.integers(4, 7)))]
            pattern = str(rng.choice(["picture", "blobs"]))
            return {"kind": "diffuse", "reflectance": self._texture(pattern, spectra)}
        if cls == "tile":  # 10–15 cm tiles on worktops and table tops
            s = 1 / (4 * float(rng.uniform(0.1, 0.15)))
            return {"kind": "roughplastic", "alpha": 0.08, "reflectance": self._texture(
                "tiles", [self.spectrum("paint"), self.spectrum("tile"), self.spectrum("tile")], (s, s), grout=0.04)}
        if cls in ("ceramic", "plastic", "leather"):
            alpha = {"ceramic": (0.03, 0.12), "plastic": (0.1, 0.4), "leather": (0.25, 0.5)}[cls]
            return {"kind": "roughplastic", "reflectance": self.spectrum(cls),
                    "alpha": round(float(rng.uniform(*alpha)), 3)}
        # paint, accent, ceiling, paper, plant, soil, food: Lambertian
        return {"kind": "diffuse", "reflectance": self.spectrum(cls)}
