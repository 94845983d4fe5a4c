"""Frozen datasets from a cube store, in the formats people train and test with (``illumix export``).

A room of its own above :mod:`retarget`, :mod:`store` and :mod:`service`: every raw frame is composed
in-process by the service's own pipeline (:mod:`dataset_export.frames`: ``make_context`` + ``SampleSpec`` +
``build_sample``), so an exported frame holds exactly what ``GET /sample`` answers for the parameters
the manifest records. One concept per module:

- :mod:`dataset_export.formats` — the format registry (``lsmi``, ``dng``, ``exr``; case-insensitive, aliases);
- :mod:`dataset_export.plan` — which places (scene, view, lighting) a run writes, for which cameras;
- :mod:`dataset_export.frames` — composing one place's LSMI capture set (``_1``, ``_12``, …) at one exposure;
- :mod:`dataset_export.chart` — the ColorChecker's corners in the image, found in the view's albedo AOV;
- :mod:`dataset_export.lsmi` — the LSMI release's layout (tiff / npy / meta.json / split.json / template DNG);
- :mod:`dataset_export.splits` — train/val/test by scene; :mod:`dataset_export.journal` — atomic writes, resume,
  checksums, ``manifest.json``; :mod:`dataset_export.card` — the dataset card ``README.md``;
- :mod:`dataset_export.run` — the whole export (what ``illumix export`` calls).

The file encoders themselves (DNG, spectral OpenEXR) live one room below, in :mod:`imagefiles`, so
that the service serves the same files (``GET /sample?format=dng|exr``).
"""
