"""The Mitsuba 3 backend (:mod:`renderer_jobs.backends`): the only package that imports ``mitsuba``.

- :mod:`.backend` — ``BACKEND``: one job at a time (a view's AOVs, or one group's cube, probed and
  guided first), on the process pool or as Ray tasks;
- :mod:`.render` — :func:`~.render.render_cube`: every band on every path in Mitsuba's own loop
  (:mod:`.band_render`, :mod:`.bands`) or four wavelengths per path (:mod:`.hero_paths`), the
  illumination cube from the same paths;
- :mod:`.scene_dict`, :mod:`.textures`, :mod:`.variant` — the scene as Mitsuba's dict, spectral
  textures, the variant choice (``llvm_ad_spectral``; ``cuda_ad_spectral`` on a GPU);
- :mod:`.trace` — numpy-driven paths and the guides' rays; :mod:`.aovs` — albedo, normal, depth,
  masks; :mod:`.denoise_guides` — the denoiser's direct-light guide (used for every backend's cubes);
- :mod:`.light_probe`, :mod:`.view_coverage`, :mod:`.boost_paths`, :mod:`.preview` — the dark-group
  probe, the pixels that see geometry, the targeted extra paths, quick previews;
- :mod:`.plastic_fit` — the roughplastic scale's table (:mod:`scene.plastic_scale`).
"""
