"""AWB evaluation: white-balance methods scored against the exact ground truth of a store or an
exported LSMI-layout dataset (``illumix evaluate``).

A room of its own above :mod:`retarget`, :mod:`store` and :mod:`service` (imports flow one way: it
uses them, nothing in them uses it):

- :mod:`awb_eval.method_names`: the method family by name (pure Python, for ``--help``);
- :mod:`awb_eval.statistical`: the Gray-Edge framework (Gray World, White Patch, Shades of Gray,
  Gray Edge of order 1 and 2), globally or patch-wise on a grid;
- :mod:`awb_eval.methods`: every method as ``raw → gain map``, the GT oracles, plug-ins;
- :mod:`awb_eval.case`: one image with its ground truth;
- :mod:`awb_eval.store_input`, :mod:`awb_eval.lsmi_input`: cases from a store or an LSMI folder
  (:mod:`awb_eval.dng_frames`: its DNG raws, read as LSMI's ``0_cvt2tiff.py`` converts them);
- :mod:`awb_eval.scoring`: per-image metrics; :mod:`awb_eval.report`: aggregates and tables;
  :mod:`awb_eval.plots`: box plots and error maps; :mod:`awb_eval.run`: the loop.
"""
