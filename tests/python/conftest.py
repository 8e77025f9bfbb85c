"""Fixtures of the Python module's tests: the `distile` command and the source folder, which
CTest passes as DISTILE_BINARY and DISTILE_SOURCE_DIR (tests/CMakeLists.txt)."""

import os
import pathlib
import subprocess

import pytest


@pytest.fixture(scope="session")
def source_dir():
    return pathlib.Path(os.environ.get("DISTILE_SOURCE_DIR",
                                       pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture(scope="session")
def distile_command():
    """Runs `distile ARGS...`; returns the completed process (output as text)."""
    binary = os.environ.get("DISTILE_BINARY")
    if not binary:
        pytest.skip("DISTILE_BINARY (the distile command) is not set")

    def run(*arguments, cwd=None):
        return subprocess.run([binary, *map(str, arguments)], capture_output=True, text=True,
                              cwd=cwd)

    return run
