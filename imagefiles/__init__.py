"""File formats illumix writes, as bytes or files: the low-level encoders both :mod:`service` (``GET
/sample?format=dng|exr``) and :mod:`dataset_export` (``illumix export``) use.

A room below :mod:`service` and :mod:`dataset_export`: it imports numpy, colour-science, :mod:`retarget` and,
inside its functions, the optional packages of the ``export`` extra (pidng, OpenEXR) — nothing above.
One concept per module:

- :mod:`imagefiles.dng` — Bayer or LinearRaw DNG raws (pidng) with colour matrix and as-shot neutral, read by libraw;
- :mod:`imagefiles.spectral_exr` — spectral OpenEXR (Fichet et al. 2021 channel names), writer and reader;
- :mod:`imagefiles.layered_exr` — a sample's outputs as one multi-channel float32 OpenEXR
  (``raw.R``, ``mixture.<group>``, ``mask``, spectra as ``S0.<λ>nm`` / ``T.<λ>nm``), writer and reader.
"""
