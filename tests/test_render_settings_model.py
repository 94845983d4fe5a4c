"""One RenderSettings (issue 34): the command line's render options, a dataset config's ``render:``
section and what jobs carry between processes all come from its fields."""

from __future__ import annotations

import inspect

from illumix.cmd_render import render
from illumix.dataset_config import RenderSection
from illumix.renderer_jobs.render_settings import RenderSettings


def test_the_cli_offers_every_cli_field_with_its_description_as_help():
    params = inspect.signature(render).parameters
    for name in RenderSettings.cli_fields():
        option = params[name].default
        assert RenderSettings.model_fields[name].description in option.help, name
    assert "max_lanes" not in params and "probe_ratio" not in params  # internal fields stay internal


def test_the_dataset_config_render_section_has_the_same_fields_and_defaults():
    section = RenderSection()
    for name in RenderSettings.cli_fields():
        f = RenderSettings.model_fields[name]
        unset = (f.json_schema_extra or {}).get("cli_unset")
        assert getattr(section, name) == (None if unset else f.default), name
    assert {"workers", "executor", "address", "views", "groups", "resolution"} <= set(RenderSection.model_fields)


def test_jobs_carry_the_settings_as_json_and_get_them_back():
    import json

    s = RenderSettings(spp=32, seed=7, resolution=(40, 30), denoise="none", sampler="Low-Discrepancy")
    back = RenderSettings(**json.loads(json.dumps(s.to_dict())))
    assert back == s and back.resolution == (40, 30) and back.sampler == "ldsampler" and back.denoise is None
