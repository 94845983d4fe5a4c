"""Benchmark: ``illumix evaluate`` — time per image per method, and the baseline table on a demo dataset.

A demo store (the procedural demo room, ``--rooms`` seeds × its 2 views, rendered at
``--resolution``/``--spp`` into ``--store`` unless already there) is evaluated with every built-in
method over ``--pairs`` through :mod:`awb_eval` exactly as the command does. Reported:

- ``compose_ms``: composing one image with the service's pipeline (``engine.sampling.build_sample``);
- per method ``ms`` (the method alone, per image) and ``ratio_to_gray_world`` (baseline of the same run);
- ``score_ms``: scoring one method on one image (angular error map + ΔE00 grid);
- the aggregate table (angular error °, ΔE00 grid worst 25 %) per method and per pair, plus the
  Gray-Edge variants e^{1,5,2} and e^{2,5,2} (the authors' demo setting) beside the defaults
  e^{1,1,6} and e^{2,1,1} (:data:`awb_eval.methods.STATISTICAL`).

Usage: ``python bench/evaluate.py [--store /tmp/illumix-bench-evaluate] [--rooms 5] [--resolution 320x240]
[--spp 16]``. Progress on stderr; the JSON result is the last line on stdout.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from illumix.awb_eval.method_names import AWB_METHODS  # noqa: E402
from illumix.awb_eval.methods import Method, resolve, statistical_gain  # noqa: E402
from illumix.awb_eval.report import aggregate, markdown  # noqa: E402
from illumix.awb_eval.run import evaluate  # noqa: E402
from illumix.awb_eval.store_input import StoreCases  # noqa: E402


def log(msg: str) -> None:
    print(f"[bench/evaluate] {msg}", file=sys.stderr, flush=True)


def ensure_store(store: Path, rooms: int, resolution: str, spp: int) -> float:
    """Render the demo rooms not yet in ``store`` (a rerun skips complete cubes); seconds spent."""
    t0 = time.perf_counter()
    for seed in range(rooms):
        log(f"render demo room {seed} ({resolution}, spp {spp}) into {store}")
        subprocess.run([sys.executable, "-m", "illumix.cli", "render", "--demo", "--demo-seed", str(seed),
                        "--store", str(store), "--resolution", resolution, "--spp", str(spp)],
                       cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


class TimedCases:
    """The store's cases, timing each composition."""

    def __init__(self, src: StoreCases) -> None:
        self.src, self.compose_s = src, []

    def __len__(self) -> int:
        return len(self.src)

    def __iter__(self):
        for job in self.src.jobs:
            t0 = time.perf_counter()
            case = self.src.compose(job)
            self.compose_s.append(time.perf_counter() - t0)
            yield case


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--store", default="/tmp/illumix-bench-evaluate")
    ap.add_argument("--rooms", type=int, default=5)
    ap.add_argument("--resolution", default="320x240")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--pairs", default="A,D65;FL11,D50;LED-B1,D75")
    ap.add_argument("--sensor", default=None)
    args = ap.parse_args()
    render_s = ensure_store(Path(args.store), args.rooms, args.resolution, args.spp)
    variants = [Method(f"{name} e^{{{n},5,2}}", lambda c, name=name: statistical_gain(c.raw, name, valid=c.usable, p=5, sigma=2))
                for name, n in (("Gray Edge", 1), ("2nd Order Gray Edge", 2))]
    methods = resolve(AWB_METHODS.names) + variants
    labels = [m.label for m in methods]
    src = TimedCases(StoreCases(args.store, pairs=args.pairs, sensor=args.sensor))
    log(f"evaluate {len(labels)} methods on {len(src)} images")
    t0 = time.perf_counter()
    res = evaluate(src, methods)
    total = time.perf_counter() - t0
    summary = aggregate(res, labels)
    n = len(res.images)
    compose_ms = 1e3 * sum(src.compose_s) / n
    method_ms = {m: summary["methods"][m]["ms"] for m in labels}
    score_ms = (1e3 * total - compose_ms * n - sum(method_ms.values()) * n) / (n * len(labels))
    gw = method_ms["Gray World"]
    print(markdown(summary, title=f"AWB baselines: {n} images, {args.resolution}, pairs {args.pairs}"), file=sys.stderr)
    doc = {
        "bench": "evaluate", "images": n, "resolution": args.resolution, "spp": args.spp, "rooms": args.rooms,
        "pairs": args.pairs.split(";"), "sensor": src.src.sensor, "render_s": round(render_s, 1),
        "evaluate_s": round(total, 2), "compose_ms": round(compose_ms, 2), "score_ms": round(score_ms, 2),
        "methods": {m: {"ms": round(method_ms[m], 2), "ratio_to_gray_world": round(method_ms[m] / gw, 2),
                        **{k: round(summary["methods"][m][k], 3) for k in
                           ("angular_mean", "angular_median", "angular_worst25", "grid_de00_worst25")}}
                    for m in labels},
        "pairs_table": {p: {m: {k: round(v[k], 3) for k in ("angular_mean", "grid_de00_worst25")} for m, v in by.items()}
                        for p, by in summary["pairs"].items()},
        "python": platform.python_version(), "machine": platform.machine(),
    }
    print(json.dumps(doc))


if __name__ == "__main__":
    main()
