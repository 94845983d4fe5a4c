"""Schemathesis reaches the success paths (issue 36, item 7): requests generated from the service's
own OpenAPI schema (positive mode: what the schema calls valid) are answered 200/201 on ``GET /sample``,
``POST /batch``, ``POST /sensors`` and ``POST /illuminants`` — counted per route — and never 5xx; an
upload is never refused for its name (201, or 409 for a name already taken).

Everything but an upload's file content comes from the schema: names from the declared name pattern,
flags, sample parameters from their patterns and enums. A schema cannot say that a CSV is a usable
spectrum, so the test draws the file (smooth positive curves on 380-780 nm) and generation does the
rest. Bounded: ``EXAMPLES`` cases per route, a fixed seed (derandomized), and ``BUDGET_S`` seconds of
sending after which the remaining cases are skipped (the counts still have to be reached).
"""

from __future__ import annotations

import math
import os
import time
from collections import Counter

import pytest

schemathesis = pytest.importorskip("schemathesis", reason="the test extra installs schemathesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from schemathesis.specs.openapi.checks import positive_data_acceptance  # noqa: E402

import synthetic_store as synth  # noqa: E402
from illumix.engine.limits import Limits  # noqa: E402
from illumix.service.app import create_app  # noqa: E402
from illumix.store import CubeStore  # noqa: E402

TOKEN = "success-token"
#: per route; a long run: ILLUMIX_SUCCESS_EXAMPLES=2000 ILLUMIX_SUCCESS_BUDGET_S=3000 pytest -s this file
EXAMPLES = int(os.environ.get("ILLUMIX_SUCCESS_EXAMPLES", "100"))
BUDGET_S = float(os.environ.get("ILLUMIX_SUCCESS_BUDGET_S", "45"))  # of sending, all routes together
MIN_SUCCESSES = 4  # per route
ROUTES = ("GET /sample", "POST /batch", "POST /sensors", "POST /illuminants", "GET /explore/frame")
MUST_SUCCEED = ("GET /sample", "POST /batch", "POST /sensors", "POST /illuminants")
#: an upload the schema calls valid, with a usable file, is stored — or meets its namesake (409)
UPLOADS = {"POST /sensors": {201, 409}, "POST /illuminants": {201, 409}}
WAVELENGTHS = range(380, 781, 20)


@pytest.fixture(scope="module")
def schema(tmp_path_factory):
    path = tmp_path_factory.mktemp("success") / "store"
    synth.build(path, h=24, w=32, extras=False)
    # the bounds of tests/test_fuzz_api.py: small frames and limits keep every request cheap
    app = create_app(CubeStore.open(str(path), mode="a"), token=TOKEN, cache_mb=16,
                     limits=Limits(max_side=256, max_pixels=256 * 256, max_batch=4, max_request_mb=64,
                                   inflight_mb=64, queue_timeout_s=5, body_timeout_s=2))
    return schemathesis.openapi.from_asgi("/openapi.json", app)


def _bell(w: float, centre: float, width: float) -> float:
    return math.exp(-(((w - centre) / width) ** 2))


@st.composite
def sensor_csv(draw) -> bytes:
    """Three bell curves, red above green above blue, of random centres and widths."""
    bells = [(draw(st.floats(lo, lo + 50)), draw(st.floats(25, 60))) for lo in (580, 510, 430)]
    rows = [f"{w}," + ",".join(f"{_bell(w, c, s):.4f}" for c, s in bells) for w in WAVELENGTHS]
    return ("wavelength,r,g,b\n" + "\n".join(rows)).encode()


@st.composite
def illuminant_csv(draw) -> bytes:
    """A positive SPD: a random tilt and ripples over the whole range."""
    tilt = draw(st.floats(-0.6, 0.6))
    ripple = draw(st.lists(st.floats(0.0, 0.3), min_size=len(WAVELENGTHS), max_size=len(WAVELENGTHS)))
    rows = [f"{w},{1 + tilt * (w - 580) / 400 + r:.4f}" for w, r in zip(WAVELENGTHS, ripple)]
    return ("wavelength,value\n" + "\n".join(rows)).encode()


FILES = {"POST /sensors": sensor_csv(), "POST /illuminants": illuminant_csv()}


def _run_route(op, label: str, statuses: Counter, started: float) -> None:
    files = FILES.get(label, st.none())

    @given(case=op.as_strategy(), content=files)
    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    def run(case, content):
        if time.monotonic() - started > BUDGET_S:
            statuses["skipped (time budget)"] += 1
            return
        if content is not None and isinstance(case.body, dict):
            case.body["file"] = content
        response = case.call(headers={"Authorization": f"Bearer {TOKEN}"})
        statuses[response.status_code] += 1
        assert response.status_code < 500, (label, case.query, str(case.body)[:300], response.text[:300])
        if response.status_code < 300:  # a success must also be what the schema documents
            case.validate_response(response, excluded_checks=[positive_data_acceptance])

    run()


def test_generated_requests_reach_the_success_paths(schema):
    started = time.monotonic()
    counts: dict[str, Counter] = {}
    for result in schema.get_all_operations():
        op = result.ok()
        label = f"{op.method.upper()} {op.path}"
        if label in ROUTES:
            counts[label] = Counter()
            _run_route(op, label, counts[label], started)
    elapsed = time.monotonic() - started
    summary = "; ".join(f"{label}: {dict(c)}" for label, c in counts.items())
    print(f"\nschemathesis success run, {elapsed:.1f} s: {summary}")
    assert set(counts) == set(ROUTES), summary
    for label in MUST_SUCCEED:
        ok = sum(n for s, n in counts[label].items() if isinstance(s, int) and 200 <= s < 300)
        assert ok >= MIN_SUCCESSES, f"{label}: {ok} successes of {sum(counts[label].values())}; {summary}"
    for label, allowed in UPLOADS.items():  # the name's schema is the server's rule: no name is refused
        assert set(counts[label]) - {"skipped (time budget)"} <= allowed, summary
