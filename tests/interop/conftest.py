"""Shared fixtures for the interop tests: real third-party tools against our outputs."""
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    return REPO


@pytest.fixture(scope="session")
def sadesim() -> str:
    """Path of the debug `sadesim` binary, built if missing."""
    exe = REPO / "target" / "debug" / "sadesim"
    if not exe.exists():
        subprocess.run(["cargo", "build", "-p", "sadesim"], cwd=REPO, check=True)
    return str(exe)


@pytest.fixture(scope="session")
def venv_bin() -> pathlib.Path:
    return pathlib.Path(os.environ.get("VIRTUAL_ENV", REPO / ".venv")) / "bin"
