"""Issue 38, the client: without torch, ``IllumixDataset`` fails with one error naming the extra to
install and the CPU-only build (the rest of the client works); the dataset runs torch with one
intra-op thread while it is iterated and gives the setting back; the README says both."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CLIENT = ROOT / "clients" / "python"


def _python(code: str, *paths: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([*map(str, paths), str(CLIENT),
                                                        os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env, check=False,
                          cwd=ROOT)


def test_dataset_without_torch_names_the_extra():
    r = _python(
        "import sys\n"
        "sys.modules['torch'] = None  # as if torch were not installed\n"
        "import illumix_client\n"
        "from illumix_client import Client, IllumixError  # the client itself needs no torch\n"
        "try:\n"
        "    from illumix_client import IllumixDataset\n"
        "except ModuleNotFoundError as exc:\n"
        "    print(type(exc).__name__, exc.name, isinstance(exc, ImportError))\n"
        "    print(exc)\n")
    assert r.returncode == 0, r.stderr
    first, message = r.stdout.splitlines()[:2]
    assert first == "ModuleNotFoundError torch True"
    assert 'pip install "clients/python[torch]"' in message
    assert "pip install torch --index-url https://download.pytorch.org/whl/cpu" in message


def test_a_broken_torch_install_is_not_blamed_on_the_extra(tmp_path):
    fake = tmp_path / "torch"
    fake.mkdir()
    (fake / "__init__.py").write_text("import a_dependency_torch_lost_xyz\n")
    r = _python("from illumix_client import IllumixDataset", tmp_path)
    assert r.returncode != 0
    assert "No module named 'a_dependency_torch_lost_xyz'" in r.stderr and "clients/python[torch]" not in r.stderr


# -- threads ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def local_store(tmp_path_factory):
    pytest.importorskip("torch")
    import synthetic_store

    path = tmp_path_factory.mktemp("threads") / "store"
    synthetic_store.build(path, extras=False)
    return str(path)


@pytest.fixture
def two_threads():
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    yield torch
    torch.set_num_threads(before)


def _dataset(store: str, **kw):
    from illumix_client import IllumixDataset

    return IllumixDataset(store=store, illuminants=["A", "D65"], sensors=["XYZ"], crop=(16, 16),
                          epoch_length=8, batch_size=4, seed=0, warm=False, **kw)


def test_one_thread_while_iterating_then_restored(local_store, two_threads):
    torch = two_threads
    from torch.utils.data import DataLoader

    seen = []
    for batch in DataLoader(_dataset(local_store), batch_size=4, num_workers=0):
        seen.append(torch.get_num_threads())  # the collate ran with it, in this process
        assert batch["raw"].shape == (4, 3, 16, 16)
    assert seen == [1, 1]
    assert torch.get_num_threads() == 2  # given back at the end of the epoch

    it = iter(_dataset(local_store, threads=3))
    next(it)
    assert torch.get_num_threads() == 3
    it.close()  # a loop left early: restored when the iterator is closed
    assert torch.get_num_threads() == 2


def test_threads_none_leaves_torch_alone(local_store, two_threads):
    torch = two_threads
    it = iter(_dataset(local_store, threads=None))
    next(it)
    assert torch.get_num_threads() == 2
    with pytest.raises(ValueError, match="threads"):
        _dataset(local_store, threads=0)


def test_readme_documents_cpu_install_and_threads():
    text = (CLIENT / "README.md").read_text()
    assert "pip install torch --index-url https://download.pytorch.org/whl/cpu" in text
    assert "**Threads.**" in text and "threads=None" in text and "OMP_NUM_THREADS=1" in text
