"""What LSMI's trainers learn from: the mixture ``.npy`` that, with ``meta.json``'s ``Light<i>``, is
their ground truth — ``illum = Σ_i mixture_i · Light_i`` (LSMI's ``mix_chroma``; its preprocessing
divides the raw by it for ``<frame>_gt.tiff``, its dataloader takes R and B of it as ``gt_illum``).

``illumix export --gt`` chooses what that model carries (:data:`TARGETS`):

- ``mixture`` (default) — each light's share of the pixel's green, as the service's ``mixture``
  output gives it (the physical ground truth's ``U_{g,G}/U_G`` where the store has illumination
  cubes, else thesis eq. 3.3): the lights' white points mixed by how much of each arrives. Bounce
  light tinted by coloured surfaces is not in it (the model stays in the span of the lights' white points);
- ``physical`` — the coefficients whose LSMI model is closest to illumix's **physical ground
  truth** (the ``illum`` output: illumination cubes relit, bounce light included): per pixel the
  non-negative least-squares fit of ``Σ_i m_i · Light_i`` to ``illum`` (both with G = 1), rescaled
  to sum to 1 so that the model's G stays 1 (:func:`fit_mixture`). Where the physical white point is a
  non-negative mix of the lights' white points (no tint from the walls, or three lights spanning it)
  the model reproduces it exactly; elsewhere it is the nearest point LSMI's model can express, and the
  angle left over is stated (``LSMIModelErrorDeg``, the card). A one-light frame has no mixture file
  (LSMI uses ``Light1`` everywhere), so it carries nothing per pixel in either target;
- ``formula`` — thesis eq. 3.3 for the ground truth itself (the model is then exact by construction).

The exact physical ground truth is always in ``<frame>_gt_illum.npy`` besides.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

TARGETS = {
    "mixture": "each light's share of the pixel's green (the service's mixture output), the lights' white points "
               "mixed by it",
    "physical": "coefficients fitted to illumix's physical ground truth (bounce light included): per pixel the non-negative "
                "least-squares mix of the lights' white points closest to it, summing to 1",
    "formula": "thesis eq. 3.3 weights (the formula ground truth itself)",
}


def fit_mixture(illum: np.ndarray, lights: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``(H, W, k)`` float32 coefficients ``m ≥ 0``, ``Σ m = 1``, whose ``Σ_i m_i · lights_i`` is nearest
    to ``illum`` per pixel (module docstring); 0 where not ``valid``.

    illum : ``(H, W, 3)`` white point per pixel (camera RGB, G = 1); lights : ``(k, 3)`` the lights'
    white points (G = 1), ``1 ≤ k ≤ 3``; valid : ``(H, W)`` bool. Exact non-negative least squares in
    RGB by enumerating the supports (``2^k − 1`` of them, each one pseudo-inverse shared by every
    pixel): the feasible least-squares solution of smallest residual.
    """
    a = np.asarray(lights, np.float64).T  # (3, k)
    k = a.shape[1]
    g = np.asarray(illum, np.float64)[valid]  # (N, 3)
    best = np.zeros((g.shape[0], k))
    best_res = np.full(g.shape[0], np.inf)
    for size in range(1, k + 1):
        for support in combinations(range(k), size):
            sub = a[:, support]
            m = g @ np.linalg.pinv(sub).T  # (N, |S|): least squares on this support
            res = np.sum((g - m @ sub.T) ** 2, axis=1)
            take = np.all(m >= 0, axis=1) & (res < best_res)
            best_res = np.where(take, res, best_res)
            best[np.ix_(take, support)] = m[take]
    total = best.sum(axis=1, keepdims=True)
    best = np.where(total > 0, best / np.where(total > 0, total, 1), 1.0 / k)
    out = np.zeros((*valid.shape, k), np.float32)
    out[valid] = best
    return out


def light_mixture(mixture: np.ndarray, which: list[int | None], k: int) -> np.ndarray:
    """``(H, W, k)`` each light's share from the per-group ``mixture`` ``(H, W, G)``: the sum over the
    groups it lights (``which[g]``: the light of group ``g``, ``None`` when off)."""
    out = np.zeros((*mixture.shape[:2], k), np.float32)
    for g, j in enumerate(which):
        if j is not None:
            out[..., j] += mixture[..., g]
    return out
