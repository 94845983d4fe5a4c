"""Property-based fuzzing of the whole HTTP API from its own OpenAPI schema (schemathesis).

For every operation, with and without the write token, schemathesis generates requests from
``/openapi.json`` (valid ones and, in its negative mode, invalid ones) and checks each answer: no
server error, status code and content type documented, body conforming to the documented schema —
plus our own check that no JSON or npz answer carries NaN or inf.

The default suite runs a short, seeded run (``ILLUMIX_FUZZ_EXAMPLES`` examples per operation, 12 by
default); ``pytest -m slow tests/test_fuzz_api.py`` runs a long one (200 per operation).
"""

from __future__ import annotations

import io
import json
import os

import numpy as np
import pytest

schemathesis = pytest.importorskip("schemathesis", reason="the test extra installs schemathesis")
from hypothesis import HealthCheck, settings  # noqa: E402
from schemathesis.specs.openapi.checks import positive_data_acceptance  # noqa: E402

import synthetic_store as synth  # noqa: E402
from illumix.service.app import create_app  # noqa: E402
from illumix.engine.limits import Limits  # noqa: E402
from illumix.store import CubeStore  # noqa: E402

TOKEN = "fuzz-token"
EXAMPLES = int(os.environ.get("ILLUMIX_FUZZ_EXAMPLES", "12"))
SLOW_EXAMPLES = 200


@pytest.fixture(scope="module")
def api(tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "store"
    synth.build(path, h=24, w=32)
    # Small frames and limits keep every generated request cheap; the limits are what is fuzzed.
    app = create_app(CubeStore.open(str(path), mode="a"), token=TOKEN, cache_mb=16,
                     limits=Limits(max_side=256, max_pixels=256 * 256, max_batch=4, max_request_mb=64,
                                   inflight_mb=64, queue_timeout_s=5, body_timeout_s=2))
    return schemathesis.openapi.from_asgi("/openapi.json", app)


schema = schemathesis.pytest.from_fixture("api")


@schemathesis.check
def finite_bodies(ctx, response, case):
    """No NaN or inf in a JSON body or in any array of an npz body."""
    ctype = response.headers.get("content-type", [""])
    ctype = ctype[0] if isinstance(ctype, list) else ctype
    if "json" in ctype:
        json.loads(response.content, parse_constant=lambda c: _fail(f"JSON answer holds {c}"))
    elif response.status_code == 200 and ctype.startswith("application/octet-stream"):
        with np.load(io.BytesIO(response.content), allow_pickle=False) as z:
            for k in z.files:
                a = z[k]
                if a.dtype.kind == "f" and not np.isfinite(a).all():
                    _fail(f"npz array {k} holds NaN/inf")
                if a.dtype.kind == "U":
                    json.loads(str(a), parse_constant=lambda c: _fail(f"{k} JSON holds {c}"))
    return None


def _fail(msg: str):
    raise AssertionError(msg)


def _run(case, with_token: bool) -> None:
    """Every built-in check (server errors, documented status codes, content types, headers and
    response schemas, invalid input rejected, …) plus :func:`finite_bodies` — except
    ``positive_data_acceptance``: a schema cannot say that a crop must lie inside the chosen view's
    frame or that a sample must fit the memory limit, so some schema-valid requests are rightly 413/422."""
    headers = {"Authorization": f"Bearer {TOKEN}"} if with_token else None
    case.call_and_validate(headers=headers, additional_checks=[finite_bodies],
                           excluded_checks=[positive_data_acceptance])


_SETTINGS = dict(deadline=None, derandomize=True, database=None,
                 suppress_health_check=list(HealthCheck))


@schema.parametrize()
@settings(max_examples=EXAMPLES, **_SETTINGS)
def test_api_with_token(case):
    _run(case, True)


@schema.parametrize()
@settings(max_examples=max(4, EXAMPLES // 2), **_SETTINGS)
def test_api_without_token(case):
    _run(case, False)


@pytest.mark.slow
@schema.parametrize()
@settings(max_examples=SLOW_EXAMPLES, **_SETTINGS)
def test_api_long_run(case):
    _run(case, True)
