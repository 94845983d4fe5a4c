"""The composition engine: a sample request resolved, priced and composed from the cube store.

Below the HTTP layer: :mod:`service` maps its errors (:mod:`engine.errors`) to status codes and
encodes its arrays; ``illumix export``, ``illumix evaluate`` and the client's local mode call it
directly, so what they write, score and return is what ``GET /sample`` serves.

- :mod:`engine.spec` — the sample request (``SampleSpec``: names, lighting, outputs, window, noise);
- :mod:`engine.plan` — resolve a request from metadata alone (no cube read);
- :mod:`engine.sampling` — price it (:mod:`engine.budget`) and compose it (numpy, or torch:
  :mod:`engine.torch_sampling`), with :mod:`engine.extra_outputs` and :mod:`engine.sample_meta`;
- :mod:`engine.cubes` — decoded cubes through the LRU cache; :mod:`engine.projections` — whole-frame
  camera projections; :mod:`engine.library` — sensors and illuminants, built-in and uploaded;
- :mod:`engine.context` — one composition context (store, library, caches, limits, memory budget);
- :mod:`engine.warm` — fill the caches before the first request.
"""
