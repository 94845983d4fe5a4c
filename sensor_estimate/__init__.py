"""Any camera without measured curves: spectral sensitivities estimated from what a raw file carries
(DNG colour matrices), under a prior learned from measured cameras (issue 35).

- :mod:`sensor_estimate.prior` — the measured sets on the grid and the Gaussian prior over curves;
- :mod:`sensor_estimate.fit` — colour matrices ↔ curves: the DNG-convention matrix of given curves,
  and the posterior of the curves given one or two matrices.

Above :mod:`retarget` only; the command line (``illumix sensors estimate``) wires it.
"""
