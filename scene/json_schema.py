"""The scene format as a JSON Schema (draft 2020-12), generated from the pydantic model.

:func:`scene_json_schema` is :meth:`pydantic.BaseModel.model_json_schema` of
:class:`scene.model.Scene` (validation mode: what a file may hold) with an ``$id``, a title and the
format version added. It is published in the repository as ``docs/scene.schema.json`` (a test keeps
that file equal to this function's output) and printed by ``illumix scenes schema``; editors
(VS Code's YAML extension: ``# yaml-language-server: $schema=…``) and ``jsonschema`` validate scene
files with it.

What the schema cannot say, loading still checks (:mod:`scene.load`): names that must resolve
(materials, light groups), duplicate names, a name with '..', files and library spectra that must exist, a sphere's
uniform scale, reflectances ≤ 1. It describes version :data:`scene.migrate.CURRENT`; files of older
versions are migrated on load (:mod:`scene.migrate`), not by the schema.
"""

from __future__ import annotations

import json

from illumix.scene.migrate import CURRENT, SUPPORTED

SCHEMA_ID = f"urn:illumix:scene:{CURRENT}"  # no published URL yet: a name, not a location
DIALECT = "https://json-schema.org/draft/2020-12/schema"


#: Shape and light names are the renderer's object keys: the schema's name pattern without '.' (format
#: version 2; :mod:`scene.migrate`), which pydantic checks with a validator the generated schema cannot show.
KEY_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_+\-]*$"


def _renderer_keys(body: dict) -> None:
    """Give every shape and light model's ``name`` :data:`KEY_PATTERN` (in place)."""
    from typing import get_args

    from illumix.scene import schema

    for union in (schema.Shape, schema.Light):
        for cls in get_args(get_args(union)[0]):
            name = body.get("$defs", {}).get(cls.__name__, {}).get("properties", {}).get("name")
            if name is not None:
                name["pattern"] = KEY_PATTERN
                name["description"] = "a renderer key: letters, digits, _ + - (no '.')"


def scene_json_schema() -> dict:
    """The JSON Schema of a scene document (module docstring)."""
    from illumix.scene.model import Scene

    body = Scene.model_json_schema(mode="validation")
    _renderer_keys(body)
    head = {"$schema": DIALECT, "$id": SCHEMA_ID, "title": f"illumix scene, format version {CURRENT}",
            "description": (f"One scene of illumix (scene/model.py): materials with measured spectra, shapes, "
                            f"lights in light groups, views. Format version {CURRENT}; illumix reads versions "
                            f"{', '.join(map(str, SUPPORTED))} (older ones are migrated on load). A file may "
                            "instead hold {scenes: [scene, ...]}. References between objects, files and "
                            "library spectra are checked when illumix loads the file, not here.")}
    return head | {k: v for k, v in body.items() if k not in ("title", "description")}


def schema_text() -> str:
    """:func:`scene_json_schema` as the text of ``docs/scene.schema.json`` (2-space indent, newline at the end)."""
    return json.dumps(scene_json_schema(), indent=2, ensure_ascii=False) + "\n"
