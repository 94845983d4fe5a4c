"""``illumix --help`` / ``--version`` start fast (no heavy import), and options with fixed choices show
them in ``--help``, accept every spelling their registry accepts, and refuse the rest (exit 2).

Import checks run in a fresh interpreter (this process has everything loaded); no timing asserts.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib.metadata import version

import pytest

from cli_testutil import run_cli
from conftest import REPO_ROOT
from test_cli_spectra import assert_one_line_error

# Each costs 0.1-1 s to import; none is needed to print help. (pydantic is typer's own parser.)
HEAVY = {"colour", "numpy", "scipy", "zarr", "mitsuba", "drjit", "fastapi", "uvicorn", "cv2", "ray",
         "httpx", "yaml", "store", "service"}

PROBE = """
import json, sys
from illumix.cli import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
else:
    code = 0
# a package's name: its top level, or the room under the illumix namespace (illumix.store → store)
names = {m.split('.')[1] if m.startswith('illumix.') else m.split('.')[0] for m in sys.modules}
print(json.dumps({"code": code, "heavy": sorted(names & set(json.loads(%r)))}))
"""


def run_fresh(*argv: str) -> tuple[int, str, list[str]]:
    """``illumix ARGV`` in a new interpreter: (exit code, what it printed, heavy modules it imported)."""
    r = subprocess.run([sys.executable, "-c", PROBE % json.dumps(sorted(HEAVY)), *argv], capture_output=True,
                       text=True, timeout=120, cwd=REPO_ROOT, env={**os.environ, "COLUMNS": "200"})
    *printed, last = r.stdout.rstrip("\n").split("\n")
    doc = json.loads(last)
    return doc["code"], "\n".join(printed), doc["heavy"]


@pytest.mark.parametrize("argv", [
    ["--help"], ["--version"], ["render", "--help"], ["validate", "--help"], ["ccm", "--help"],
    ["whitepoint", "--help"], ["serve", "--help"], ["demo", "--help"], ["store", "verify", "--help"],
    ["sensors", "list", "--help"], ["dataset", "--help"], ["scenes", "generate", "--help"],
    ["scenes", "preview", "--help"],
], ids=" ".join)
def test_help_and_version_import_nothing_heavy(argv):
    code, printed, heavy = run_fresh(*argv)
    assert code == 0 and printed
    assert heavy == [], f"`illumix {' '.join(argv)}` imported {heavy}"


def test_help_shows_the_choices():
    assert "[all-bands|stratified|random]" in run_fresh("render", "--help")[1]
    assert "[multijitter|ldsampler|orthogonal|stratified|independent" in run_fresh("render", "--help")[1]
    assert "[local|ray]" in run_fresh("render", "--help")[1]
    assert "[all-bands|stratified|random]" in run_fresh("validate", "--help")[1]
    assert "[White Preserving|Unconstrained|wp|Least Squares]" in run_fresh("ccm", "--help")[1]


def test_version_end_to_end():
    r = subprocess.run([sys.executable, "-m", "illumix.cli", "--version"], capture_output=True, text=True,
                       timeout=60, cwd=REPO_ROOT)
    assert r.returncode == 0 and r.stderr == ""
    assert r.stdout == f"illumix {version('illumix')}\n" == "illumix 0.1.0\n"


@pytest.mark.parametrize("argv, valid", [
    (["render", "--demo", "--store", "{tmp}", "--wavelengths", "strat"], "(valid: all-bands, stratified, random)"),
    (["validate", "--out", "{tmp}", "--wavelengths", "uniform"], "(valid: all-bands, stratified, random)"),
    (["render", "--demo", "--store", "{tmp}", "--executor", "slurm"], "(valid: local, ray)"),
    (["ccm", "--sensor", "XYZ", "--illuminant", "A", "--method", "gray world"],
     "(valid: White Preserving, Unconstrained, wp, Least Squares)"),
])
def test_a_value_outside_the_choices_is_exit_2_naming_them(tmp_path, capsys, argv, valid):
    argv = [a.replace("{tmp}", str(tmp_path / "out")) for a in argv]
    line = assert_one_line_error(*run_cli(capsys, *argv))
    assert f"Invalid value for '{argv[-2]}'" in line and valid in line
    assert not (tmp_path / "out").exists()


def test_close_matches_are_suggested(capsys):
    line = assert_one_line_error(*run_cli(capsys, "render", "--demo", "--store", "x", "--wavelengths", "stratifed"))
    assert "did you mean 'stratified'?" in line


def test_any_registry_spelling_is_accepted_and_canonical(tmp_path, capsys):
    code, out, err = run_cli(capsys, "render", "--demo", "--store", str(tmp_path / "st"), "--dry-run", "--json",
                             "--wavelengths", "RANDOM", "--executor", "Local", "--resolution", "8x6")
    assert code == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["wavelengths"] == "random" and summary["executor"] == "local"
    code, out, err = run_cli(capsys, "ccm", "--sensor", "XYZ", "--illuminant", "D65", "--method", "least-squares",
                             "--json")
    assert code == 0, err
    assert json.loads(out)["method"] == "Unconstrained"


def test_render_settings_and_executor_accept_registry_spellings():
    from illumix.renderer_jobs import jobs
    from illumix.renderer_jobs.execute import execute
    from illumix.renderer_jobs.mitsuba.render import RenderSettings
    from illumix.renderer_jobs.modes import WAVELENGTH_MODES
    from illumix.scene.schema import SceneError

    assert RenderSettings(wavelengths="Stratified").wavelengths == "stratified"
    assert list(WAVELENGTH_MODES) == ["all-bands", "stratified", "random"] and list(jobs.EXECUTORS) == ["local", "ray"]
    with pytest.raises(SceneError, match=r"unknown wavelength sampling 'rand'; did you mean 'random'\?"):
        RenderSettings(wavelengths="rand")
    with pytest.raises(SceneError, match=r"unknown executor 'slurm' \(valid: local, ray\)"):
        execute(jobs.Plan(scenes={}, jobs=[]), "unused", RenderSettings(), executor="slurm")
    assert execute(jobs.Plan(scenes={}, jobs=[]), "unused", RenderSettings(), executor="RAY") == []


def test_demo_passes_every_render_option():
    """`illumix demo` calls the render command as a function: an option it leaves out arrives as
    typer's OptionInfo object, not its default (a missing --denoise broke the demo once)."""
    import ast
    import inspect
    from pathlib import Path

    from illumix import cmd_demo
    from illumix.cmd_render import render

    tree = ast.parse(Path(cmd_demo.__file__).read_text())
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "render"]
    assert calls, "cmd_demo no longer calls render()"
    for call in calls:
        given = {k.arg for k in call.keywords}
        assert set(inspect.signature(render).parameters) <= given, set(inspect.signature(render).parameters) - given
