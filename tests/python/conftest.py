"""Shared fixtures of the Python tests (run by ctest with PYTHONPATH=build/python and
SKELFLOW_CLI pointing at the skelflow program built with the module)."""
import os
import pathlib
import shutil
import subprocess

import pytest

DATA = pathlib.Path(__file__).parent / "data"


@pytest.fixture
def data_dir(tmp_path):
    """A scratch copy of tests/python/data (pipelines resolve their outputs next to themselves)."""
    d = tmp_path / "data"
    shutil.copytree(DATA, d)
    return d


@pytest.fixture(scope="session")
def cli():
    """Runs `skelflow ARGS...`; returns the CompletedProcess (text mode)."""
    exe = os.environ.get("SKELFLOW_CLI")
    if not exe or not os.path.exists(exe):
        pytest.fail("SKELFLOW_CLI must name the skelflow program (ctest sets it)")

    def run(*args, cwd=None):
        return subprocess.run([exe, *map(str, args)], capture_output=True, text=True, cwd=cwd)

    return run
