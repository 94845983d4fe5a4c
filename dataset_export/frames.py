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
    gain they share and ``lsmi_error_deg``: mean and max angle between LSMI's illumination model
    ``Σ mixture_i Light_i`` and the sample's ``illum`` over lit pixels of the all-lit frame (0 for
    ``gt=formula``; the bounce light's tint for ``gt=physical``)."""

    place: Place
    sensor: str
    frames: list[Frame]
    chroma: list[list[float]]
    exposure: float
    lsmi_error_deg: dict


class Composer:
    """Composes places' frames from a store (module docstring).

    gt : ``physical`` / ``formula`` / ``None`` (the service's default); size : ``(W, H)`` or ``None``;
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
        """The ``/sample`` parameters of one frame (JSON-able, in the wire's list form)."""
        k = len(place.lighting)
        lit = {int(c) - 1 for c in lights}
        p = {"scene": place.scene, "view": place.view, "sensor": sensor,
             "seed": derive_seed(place.seed, sensor, lights),
             "illuminants": [place.lighting[g] if g < k else "E" for g in range(len(place.groups))],
             "intensities": [1.0 if g in lit else 0.0 for g in range(len(place.groups))],
             "exposure": exposure, "outputs": OUTPUTS}
        if self.size:
            p["size"] = list(self.size)
        if self.gt:
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
        chroma = [[float(v) for v in meta["illuminants"][g]["white_point_rgb"]] for g in range(k)]
        lit = arrays["mask"]
        model = np.einsum("hwk,kc->hwc", arrays["mixture"][..., :k], np.float32(chroma))
        err = angular_error(model[lit], arrays["illum"][lit]) if lit.any() else np.zeros(1)
        frames = []
        for lights in sets:
            params = self.params(place, sensor, lights, "auto" if lights == full else repr(gain))
            a, m = (arrays, meta) if lights == full else self.compose(params)
            raw = a["raw"] if self.noise else simulate_raw(a["raw"], self.levels, noise=False)
            idx = [int(c) - 1 for c in lights]
            mix = None
            if len(idx) > 1:
                mix = np.where(a["mask"][..., None], a["mixture"][..., idx], np.float32(ZERO_MASK)).astype(np.float32)
            gt_illum = np.where(a["mask"][..., None], a["illum"], np.float32(ZERO_MASK)).astype(np.float32)
            frames.append(Frame(lights, params, raw.astype(np.uint16), mix, _neutral(mix, [chroma[i] for i in idx]), m,
                                gt_illum))
        return Capture(place, sensor, frames, chroma, gain,
                       {"mean": float(np.mean(err)), "max": float(np.max(err))})


def _neutral(mixture: np.ndarray | None, chroma: list[list[float]]) -> list[float]:
    """The frame's as-shot neutral (G = 1): its light's white point, or the mean of LSMI's
    illumination map ``Σ mixture_i Light_i`` over the lit pixels."""
    return as_shot_neutral(chroma, mixture, None if mixture is None else mixture[..., 0] != ZERO_MASK)
