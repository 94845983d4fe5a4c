"""A dataset config file (YAML or JSON): which scenes to render and how.

```yaml
name: interiors-v1
generated: {count: 100, seed: 0, generator: {layouts: [rect, L, two-rooms], windows: [0, 3],
                                             views: [3, 7], resolution: [240, 180], probe: true}}
scenes: [my_room.yaml, kitchen.glb]     # optional scene files, relative to this config
render: {spp: 64, seed: 0, illumination: true, workers: 2, executor: local}
```

``generated``: rooms ``room-{seed:06d}`` for seeds ``seed .. seed + count - 1`` from
:func:`scenegen.generate.generate_doc` (``generator`` is :class:`scenegen.generate.GeneratorConfig`).
``render`` is ``illumix render``'s options: the fields of
:class:`~renderer_jobs.render_settings.RenderSettings` (same names, ``_`` for ``-``; same defaults)
plus where the jobs run, checked by the same code (:mod:`illumix.render_options`). Every error is one line naming the field
(``render.spp``, ``generated.generator.windows``) and what to write instead.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    create_model,
    field_validator,
    model_validator,
)

from illumix.errors import UserError
from illumix.renderer_jobs.render_settings import RenderSettings
from illumix.scenegen.generate import GeneratorConfig


class GeneratedSection(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    count: int = Field(ge=0, le=1_000_000)
    seed: int = Field(default=0, ge=0, le=999_999)
    generator: GeneratorConfig = Field(default_factory=GeneratorConfig)

    @model_validator(mode="after")
    def _names_fit(self) -> GeneratedSection:
        if self.seed + self.count > 1_000_000:
            raise ValueError("seed + count must be <= 1000000 (room names are room-NNNNNN)")
        return self

    @property
    def seeds(self) -> range:
        return range(self.seed, self.seed + self.count)


class _RunOptions(BaseModel):
    """Where and what of a dataset render, beside its :class:`RenderSettings` fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    resolution: str | None = None  # WIDTHxHEIGHT for every view, overriding the scenes' own
    views: list[str] | None = None
    groups: list[str] | None = None
    workers: int = Field(default=1, ge=1)
    executor: str = "local"
    address: str | None = None

    @field_validator("resolution", mode="before")
    @classmethod
    def _resolution(cls, v: Any) -> Any:
        if isinstance(v, (list, tuple)) and len(v) == 2:
            return f"{v[0]}x{v[1]}"
        return v

    @field_validator("views", "groups", mode="before")
    @classmethod
    def _names(cls, v: Any) -> Any:
        if isinstance(v, str):
            v = [t.strip() for t in v.split(",") if t.strip()]
        if v is not None and not v:
            raise ValueError("names nothing; give a list of names, or leave it out for all")
        return v


def _settings_fields() -> dict[str, tuple]:
    """:class:`RenderSettings`' command-line fields, as they are (name, type, range, default); an
    option unset on the command line by default is unset here too."""
    fields = {}
    for name in RenderSettings.cli_fields():
        f = RenderSettings.model_fields[name]
        unset = (f.json_schema_extra or {}).get("cli_unset")
        fields[name] = (f.annotation | None, Field(None, description=f.description)) if unset else (f.annotation, f)
    return fields


#: ``illumix render``'s options (see ``illumix render --help``): the RenderSettings fields, and where to run.
RenderSection = create_model("RenderSection", __base__=_RunOptions, **_settings_fields())


class DatasetConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str = Field(min_length=1)
    generated: GeneratedSection | None = None
    scenes: list[str] = Field(default_factory=list)
    render: RenderSection = Field(default_factory=RenderSection)

    @model_validator(mode="after")
    def _something(self) -> DatasetConfig:
        if (self.generated is None or self.generated.count == 0) and not self.scenes:
            raise ValueError("no scenes: give generated: {count: N} and/or scenes: [FILE, ...]")
        return self


def _loc(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _hint(err: dict) -> str:
    """One pydantic error as ``field: what is wrong``."""
    where = _loc(err["loc"])
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] == "extra_forbidden":
        parent = _loc(err["loc"][:-1])
        msg = (f"unknown field {err['loc'][-1]!r}" + (f" in {parent}" if parent else "")
               + "; remove it or check the spelling (illumix dataset --help lists the fields)")
        return msg
    if err["type"] == "missing":
        return f"{where}: required; add it"
    return f"{where}: {msg}" if where else msg


def parse_config(doc: Any, source: str) -> DatasetConfig:
    """A validated :class:`DatasetConfig` of a parsed document; :class:`UserError` (one line) otherwise."""
    if not isinstance(doc, dict):
        raise UserError(f"{source}: a dataset config is a mapping with name, generated, scenes, render; "
                        f"got {type(doc).__name__}")
    try:
        return DatasetConfig.model_validate(doc)
    except ValidationError as exc:
        errs = exc.errors()
        more = f" (and {len(errs) - 1} more)" if len(errs) > 1 else ""
        raise UserError(f"{source}: {_hint(errs[0])}{more}") from None


def read_doc(path: Path) -> Any:
    """A YAML/JSON file's document; :class:`UserError` when it cannot be read or parsed."""
    import json

    import yaml

    if not path.is_file():
        raise UserError(f"config {str(path)!r} " + ("is a directory; give a YAML file" if path.is_dir()
                                                      else "does not exist"))
    try:
        text = path.read_text(encoding="utf-8")
        return json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read ({exc})") from None
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        first = " ".join(s.strip() for s in str(exc).strip().splitlines())
        raise UserError(f"{path}: not valid {'JSON' if path.suffix.lower() == '.json' else 'YAML'}: {first}") from None


def load_config(path: str | Path) -> DatasetConfig:
    """The dataset config at ``path``."""
    p = Path(path)
    return parse_config(read_doc(p), str(p))


def is_dataset_config(doc: Any) -> bool:
    """Whether a parsed document is a dataset config rather than a scene file (a scene has shapes
    and views; a config has ``generated``/``render`` or a ``scenes`` list of file names)."""
    if not isinstance(doc, dict) or "shapes" in doc or "views" in doc:
        return False
    if "generated" in doc or "render" in doc:
        return True
    sc = doc.get("scenes")
    return isinstance(sc, list) and bool(sc) and all(isinstance(x, str) for x in sc)


def config_flag(name: str) -> str:
    """How a config spells a render option in errors: ``noise-target`` → ``render.noise_target``."""
    return f"render.{name.replace('-', '_')}"
