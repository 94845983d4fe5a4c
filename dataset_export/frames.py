"""One place's frames, composed in-process by the service's own pipeline.

Each frame is ``engine.sampling.build_sample(SampleSpec(**params), ctx)`` over a
``engine.context.make_context`` of the store — what the client's local mode does — so its arrays
are exactly what ``GET /sample?<params>`` answers; ``params`` is recorded in the manifest. A place
lit by ``k`` lights yields LSMI's capture set (:func:`light_sets`: ``_1``; ``_1, _12``;
``_1, _12, _13, _123``), one frame per subset of lit groups (the others at intensity 0), all at
**one** exposure: the all-lit frame's auto exposure (thesis eq. 4.2), given to the others as a
fixed gain, so that ``_12 − _1`` is light 2 alone, as LSMI's fixed camera settings assume.

Raw frames become digital numbers of a sensor model (black level, white level; optional noise):
with noise, ``noise=`` is part of the sample parameters (the service adds photon and read noise
with the frame's seed); without, the noise-free raw is quantised the same way
(:func:`retarget.sensor_model.simulate_raw` with ``noise=False``): ``round(black + raw·(white −
black))`` clipped to ``[0, white]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from illumix.dataset_export.errors import ExportError
from illumix.dataset_export.lsmi_target import fit_mixture, light_mixture
from illumix.dataset_export.plan import Place, derive_seed
from illumix.imagefiles.dng import as_shot_neutral

OUTPUTS = ["raw", "mixture", "illum", "mask", "meta"]
ZERO_MASK = -1.0  # LSMI's mixture value where no light reaches the pixel (never NaN, never other negatives)


def light_sets(k: int) -> list[str]:
    """LSMI's files for a place with ``k`` lights: the first light alone, then each other light added
    to it, then all (``1``; ``1, 12``; ``1, 12, 13, 123``)."""
    if k == 1:
        return ["1"]
    return ["1", *(f"1{i}" for i in range(2, k + 1)), *(["".join(str(i) for i in range(1, k + 1))] if k > 2 else [])]


@dataclass
class Frame:
    """A composed frame: ``lights`` (``"12"``), ``params`` (the ``/sample`` parameters), ``dn`` raw in
    digital numbers uint16 ``(H, W, 3)`` RGB or ``(H, W)`` Bayer, ``mixture`` ``(H, W, len(lights))``
    float32 (``ZERO_MASK`` where unlit; ``None`` for one light), ``neutral`` the frame's mean white
    point (G = 1), ``meta`` the sample's metadata and ``gt_illum`` ``(H, W, 3)`` float32 the sample's
    ``illum``: the ground-truth white point per pixel (camera RGB, G = 1; physical or formula as the
    sample's ground truth), ``ZERO_MASK`` in all three channels where it is undefined."""

    lights: str
    params: dict
    dn: np.ndarray
    mixture: np.ndarray | None
    neutral: list[float]
    meta: dict = field(repr=False)
    gt_illum: np.ndarray | None = field(default=None, repr=False)


@dataclass
class Capture:
    """A place's frames plus ``chroma`` (camera-RGB white point, G = 1, per light), the ``exposure``
    gain they share, ``lsmi_error_deg``: mean and max angle between LSMI's illumination model
    ``Σ mixture_i Light_i`` (the mixture written) and the sample's ``illum`` over lit pixels of the
    all-lit frame (0 for ``gt=formula``; the bounce light's tint with the default mixture target; what
    LSMI's model cannot express of it with ``gt=physical``), and ``groups``: per light the groups it lights."""

    place: Place
    sensor: str
    frames: list[Frame]
    chroma: list[list[float]]
    exposure: float
    lsmi_error_deg: dict
    groups: list[list[str]] = field(default_factory=list)  # per light, the groups it lights


class Composer:
    """Composes places' frames from a store (module docstring).

    gt : LSMI's target (:data:`dataset_export.lsmi_target.TARGETS`): ``mixture``/``None`` (the service's
    default ground truth and its mixture), ``physical`` (the physical ground truth; mixtures fitted to
    it), ``formula``; size : ``(W, H)`` or ``None``;
    noise : the service's ``noise=`` text or ``None``; levels : the :class:`NoiseModel` whose black and
    white level quantise noise-free frames; bayer : CFA pattern (``None``: RGB frames).
    """

    def __init__(self, store, *, gt: str | None, size: tuple[int, int] | None, noise: str | None, levels,
                 bayer: str | None, cache_mb: int = 1024) -> None:
        from illumix.engine.context import make_context
        from illumix.engine.local_library import LocalLibrary

        self.ctx = make_context(store, cache_mb=cache_mb)
        self.ctx.library = LocalLibrary(store)  # sensors and illuminants also given by path
        self.gt, self.size, self.noise, self.levels, self.bayer = gt, size, noise, levels, bayer

    def params(self, place: Place, sensor: str, lights: str, exposure: str) -> dict:
        """The ``/sample`` parameters of one frame (JSON-able, in the wire's list form): ``pair=`` with
        one intensity per illuminant of the pair for a pair place (the service assigns its groups),
        else one illuminant per group (light ``i`` on group ``i``, the rest off)."""
        k = len(place.lighting)
        lit = {int(c) - 1 for c in lights}
        p = {"scene": place.scene, "view": place.view, "sensor": sensor,
             "seed": derive_seed(place.seed, sensor, lights)}
        if place.pair:
            p |= {"pair": list(place.lighting), "intensities": [1.0 if j in lit else 0.0 for j in range(k)]}
        else:
            p |= {"illuminants": [place.lighting[g] if g < k else "E" for g in range(len(place.groups))],
                  "intensities": [1.0 if g in lit else 0.0 for g in range(len(place.groups))]}
        p |= {"exposure": exposure, "outputs": OUTPUTS}
        if self.size:
            p["size"] = list(self.size)
        if self.gt in ("physical", "formula"):  # mixture: the service's default ground truth
            p["gt"] = self.gt
        if self.noise:
            p["noise"] = self.noise
        if self.bayer:
            p["bayer"] = self.bayer
        return p

    def compose(self, params: dict) -> tuple[dict[str, np.ndarray], dict]:
        """The sample's arrays and metadata; a refusal of the engine's (:mod:`engine.errors`: an HTTP
        answer in the service) becomes an :class:`ExportError` naming the place, which stops the
        export with one line."""
        from illumix.engine.errors import Busy, TooLarge
        from illumix.engine.sampling import build_sample
        from illumix.engine.spec import SampleSpec

        try:
            return build_sample(SampleSpec(**params), self.ctx)
        except (TooLarge, Busy) as exc:
            raise ExportError(f"{params['scene']}/{params['view']}: {exc}") from None

    def capture(self, place: Place, sensor: str) -> Capture:
        """Every frame of ``place`` seen by ``sensor`` (module docstring)."""
        from illumix.retarget.metrics import angular_error
        from illumix.retarget.sensor_model import simulate_raw

        k = len(place.lighting)
        sets = light_sets(k)
        full = sets[-1]
        arrays, meta = self.compose(self.params(place, sensor, full, "auto"))
        gain = float(meta["exposure_gain"])
        which = lights_of_groups(place, meta)
        first = [which.index(j) for j in range(k)]  # a group each light is on (all of its groups share it)
        chroma = [[float(v) for v in meta["illuminants"][g]["white_point_rgb"]] for g in first]
        frames, err = [], np.zeros(1)
        for lights in sets:
            params = self.params(place, sensor, lights, "auto" if lights == full else repr(gain))
            a, m = (arrays, meta) if lights == full else self.compose(params)
            raw = a["raw"] if self.noise else simulate_raw(a["raw"], self.levels, noise=False)
            idx = [int(c) - 1 for c in lights]
            mix = None
            if len(idx) > 1:
                mix = self._target(a, which, k, idx, np.float32(chroma)[idx])
                if lights == full and a["mask"].any():  # LSMI's model Σ mixture·Light against illumix's illum
                    model = np.einsum("hwk,kc->hwc", mix, np.float32(chroma)[idx])
                    err = angular_error(model[a["mask"]], a["illum"][a["mask"]])
                mix = np.where(a["mask"][..., None], mix, np.float32(ZERO_MASK)).astype(np.float32)
            gt_illum = np.where(a["mask"][..., None], a["illum"], np.float32(ZERO_MASK)).astype(np.float32)
            frames.append(Frame(lights, params, raw.astype(np.uint16), mix, _neutral(mix, [chroma[i] for i in idx]), m,
                                gt_illum))
        groups = [[g for g, j in zip(place.groups, which) if j == i] for i in range(k)]
        return Capture(place, sensor, frames, chroma, gain,
                       {"mean": float(np.mean(err)), "max": float(np.max(err))}, groups)

    def _target(self, a: dict, which: list[int | None], k: int, idx: list[int], chroma: np.ndarray) -> np.ndarray:
        """The frame's mixture ``(H, W, len(idx))`` for LSMI's files (:mod:`dataset_export.lsmi_target`):
        fitted to the physical ``illum`` for ``gt=physical``, else each light's share of the served mixture."""
        if self.gt == "physical":
            return fit_mixture(a["illum"], chroma, a["mask"])
        return light_mixture(a["mixture"], which, k)[..., idx]


def lights_of_groups(place: Place, meta: dict) -> list[int | None]:
    """Per group of the view, the light (index into ``place.lighting``) that lights it, or ``None``: a
    pair place as the service assigned it (``meta.lighting_rule``: by kind, or in order), else light
    ``i`` on group ``i``."""
    k = len(place.lighting)
    if not place.pair:
        return [g if g < k else None for g in range(len(place.groups))]
    rule = meta["lighting_rule"]
    if rule["rule"] == "kind":  # exactly one illuminant of the pair is daylight, so the two names differ
        return [None if e["illuminant"] is None else place.lighting.index(e["illuminant"]) for e in rule["groups"]]
    return [g if g < k else None for g in range(len(place.groups))]


def _neutral(mixture: np.ndarray | None, chroma: list[list[float]]) -> list[float]:
    """The frame's as-shot neutral (G = 1): its light's white point, or the mean of LSMI's
    illumination map ``Σ mixture_i Light_i`` over the lit pixels."""
    return as_shot_neutral(chroma, mixture, None if mixture is None else mixture[..., 0] != ZERO_MASK)
