"""AWB evaluation: white-balance methods scored against the exact ground truth of a store or an
exported LSMI-layout dataset (``illumix evaluate``).

A room of its own above :mod:`retarget`, :mod:`store` and :mod:`service` (imports flow one way: it
uses them, nothing in them uses it):

- :mod:`evaluate.method_names`: the method family by name (pure Python, for ``--help``);
- :mod:`evaluate.statistical`: the Gray-Edge framework (Gray World, White Patch, Shades of Gray,
  Gray Edge of order 1 and 2), globally or patch-wise on a grid;
- :mod:`evaluate.methods`: every method as ``raw → gain map``, the GT oracles, plug-ins;
- :mod:`evaluate.case`: one image with its ground truth;
- :mod:`evaluate.store_input`, :mod:`evaluate.lsmi_input`: cases from a store or an LSMI folder;
- :mod:`evaluate.scoring`: per-image metrics; :mod:`evaluate.report`: aggregates and tables;
  :mod:`evaluate.plots`: box plots and error maps; :mod:`evaluate.run`: the loop.
"""
