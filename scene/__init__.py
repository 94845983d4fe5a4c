"""The scene side's bottom room: what a scene is, independent of any renderer.

- :mod:`scene.schema` — the document's shapes, materials, lights and views (pydantic), and
  :class:`scene.spectra.SceneError`;
- :mod:`scene.model` — :class:`scene.model.Scene`: a validated scene on a spectral grid;
- :mod:`scene.load` — YAML/JSON files and dicts → scenes; :mod:`scene.spectra`,
  :mod:`scene.textures` — spectral data and spectral textures;
- :mod:`scene.demo` — the procedural demo room and the validation chart;
- :mod:`scene.plastic_scale` — the roughplastic base-colour scale the importers and the Cycles
  backend share (a table: no renderer needed);
- :mod:`scene.blender_env` — where Blender's own Python is (the ``.blend`` importer and the Cycles
  backend run Blender).

Generators (:mod:`scenegen`), importers (:mod:`scene_import`) and renderers (:mod:`renderer_jobs`)
sit above it; it imports none of them.
"""
