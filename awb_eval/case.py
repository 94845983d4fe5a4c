"""One evaluation image: camera raw plus its exact ground truth.

Built by :mod:`awb_eval.store_input` (a sample composed by the service's own pipeline) or by
:mod:`awb_eval.lsmi_input` (a file of an LSMI-layout dataset).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class Case:
    """An image and its ground truth. Shapes: ``H × W`` pixels, ``G`` illuminants.

    name : unique label (``scene/view A,D65`` or ``place_12``); pair : the lighting it is
    aggregated under (``"A,D65"``, LSMI's ``"12"``).
    raw : ``(H, W, 3)`` float32 linear camera raw (black level removed), what a method sees.
    illum : ``(H, W, 3)`` float32 GT illuminant colour per pixel (camera RGB, > 0 everywhere; any
    scale: the gain map is ``max_j illum_j / illum_k``).
    mask : ``(H, W)`` bool, pixels where the ground truth is defined (the only ones scored).
    mixture : ``(H, W, G)`` float32 share of each illuminant (0 where ``mask`` is False).
    white_points : ``(G, 3)`` float64 camera-RGB white point of each illuminant.
    ccm : ``(H, W, 3, 3)`` or ``(3, 3)`` float32 camera → linear sRGB, the same for every method
    (the GT CCM map of a store sample; the camera's DNG matrix of an LSMI folder).
    usable : ``(H, W)`` bool pixels a method may use for its statistics (not saturated), or None.
    sensor : the camera the image was made for (``random:<seed>`` for a drawn one), or "".
    """

    name: str
    pair: str
    raw: np.ndarray
    illum: np.ndarray
    mask: np.ndarray
    mixture: np.ndarray
    white_points: np.ndarray
    ccm: np.ndarray
    usable: np.ndarray | None = None
    sensor: str = ""

    @property
    def shape(self) -> tuple[int, int]:
        return self.raw.shape[:2]


@dataclass(frozen=True)
class Unusable:
    """An image that could not be made (e.g. a view that cannot be relit as asked): skipped by the
    evaluation with ``why``, so one bad view does not stop a whole store's run."""

    name: str
    pair: str
    why: str


def unsaturated(raw: np.ndarray, white: float) -> np.ndarray:
    """``(H, W)`` bool: pixels a statistical method may use — no channel at the white level, nor
    next to one (a 3×3 dilation of the saturated pixels, as van de Weijer's ``general_cc``)."""
    saturated = np.any(np.asarray(raw) >= np.float32(white), axis=-1).astype(np.uint8)
    return cv2.dilate(saturated, np.ones((3, 3), np.uint8)) == 0
