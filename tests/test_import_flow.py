"""The import flow README's "What is where" states is the code's (issue 34): one-way arrows between the
rooms, no circle among the product's modules (function-level imports included; imports under
``if TYPE_CHECKING:`` are annotations only and left out), and one installed namespace, ``illumix.*``."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: room → the rooms it may import (README, "What is where"); ``illumix`` (the CLI) wires them all.
ALLOWED = {
    "retarget": set(),
    "store": {"retarget"},
    "scene": {"retarget"},
    "renderer_jobs": {"retarget", "store", "scene"},
    "scenegen": {"retarget", "scene", "renderer_jobs"},
    "scene_import": {"retarget", "scene"},
    "imagefiles": {"retarget"},
    "engine": {"retarget", "store", "sensor_estimate"},
    "service": {"retarget", "store", "engine", "imagefiles", "sensor_estimate"},
    "dataset_export": {"retarget", "store", "engine", "imagefiles"},
    "awb_eval": {"retarget", "store", "engine"},
    "sensor_estimate": {"retarget"},
    "illumix": {"retarget", "store", "scene", "renderer_jobs", "scenegen", "scene_import", "imagefiles", "engine", "service",
                "dataset_export", "awb_eval", "sensor_estimate"},
}
CLIENT = ROOT / "clients" / "python" / "illumix_client"


def _modules() -> dict[str, Path]:
    """Installed name (``illumix.<room>.…``; the CLI's own modules ``illumix.…``) → file."""
    out = {}
    for room in ALLOWED:
        for p in (ROOT / room).rglob("*.py"):
            parts = p.relative_to(ROOT).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            out[".".join(parts if room == "illumix" else ("illumix", *parts))] = p
    return out


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in ALLOWED else "illumix"


def _imports(path: Path, known: dict[str, Path]) -> set[str]:
    """The product modules ``path`` imports (``from a.b import c`` counts ``a.b.c`` when it is a module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
            for n in ast.walk(node)}

    def resolve(name: str) -> str | None:
        while name and name not in known:
            name = name.rpartition(".")[0]
        return name or None

    out = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out |= {r for a in node.names if (r := resolve(a.name))}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out |= {r for a in node.names if (r := resolve(f"{node.module}.{a.name}"))}
    return out


def _graph() -> dict[str, set[str]]:
    known = _modules()
    return {m: _imports(p, known) - {m} for m, p in known.items()}


def test_rooms_import_only_downward():
    bad = sorted(f"{m} imports {t}" for m, targets in _graph().items() for t in targets
                 if _room(t) != _room(m) and _room(t) not in ALLOWED[_room(m)])
    assert not bad, "imports against the README's flow:\n" + "\n".join(bad)


def test_no_circular_imports_among_product_modules():
    graph = _graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    circles: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not circles, f"circular imports: {circles}"


def test_the_client_reaches_the_engine_never_the_service():
    """The client talks HTTP; its optional local mode composes with the engine, never with routes."""
    known = _modules()
    for p in CLIENT.rglob("*.py"):
        rooms = {_room(m) for m in _imports(p, known)}
        assert rooms <= {"engine", "retarget", "store"}, f"{p.name} imports {sorted(rooms)}"


def test_only_the_illumix_namespace_is_installed(tmp_path):
    """``import illumix.service`` works from anywhere; the rooms' bare names (``service``, ``store``…)
    are not importable outside the repository: they would collide with other packages."""
    import subprocess
    import sys

    code = ("import importlib.util as u, illumix.service, illumix.store, illumix.engine\n"
            f"print([r for r in {sorted(set(ALLOWED) - {'illumix'})!r} if u.find_spec(r) is not None])")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_modules_and_functions_stay_small():
    """~400 lines a module and ~60 a function (issue 34): a module over 410 lines or a function over
    70 fails here, naming where to split."""
    big = []
    for p in _modules().values():
        text = p.read_text(encoding="utf-8")
        if text.count("\n") > 410:
            big.append(f"{p.relative_to(ROOT)}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= 70:
                big.append(f"{p.relative_to(ROOT)}:{node.lineno} {node.name}: {node.end_lineno - node.lineno + 1} lines")
    assert not big, "split these:\n" + "\n".join(big)


def test_only_the_mitsuba_package_reaches_mitsuba_and_only_blender_workers_bpy():
    """Issue 34: the renderers stay behind their packages — ``mitsuba``/``drjit`` (directly or through
    ``import_mitsuba``) only in ``renderer_jobs/mitsuba/``; ``bpy`` only in the scripts Blender's own
    Python runs (the Cycles worker and the .blend reader)."""
    blender_scripts = {"renderer_jobs/cycles/worker.py", "renderer_jobs/cycles/blender_nodes.py",
                       "scene_import/blend_worker.py"}
    bad = []
    for p in _modules().values():
        rel = p.relative_to(ROOT).as_posix()
        tree = ast.parse(p.read_text(encoding="utf-8"))
        names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        names |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
        names |= {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
        if names & {"mitsuba", "drjit", "import_mitsuba"} and not rel.startswith("renderer_jobs/mitsuba/"):
            bad.append(f"{rel} reaches mitsuba")
        if "bpy" in names and rel not in blender_scripts:
            bad.append(f"{rel} imports bpy")
    assert not bad, "\n".join(bad)
