"""Shared fixtures for the interop tests: real third-party tools against our outputs."""
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
# Where cargo puts its builds: `CARGO_TARGET_DIR` when set (relative to the repository, where
# `tests/run.sh` runs cargo), else `target/`.
TARGET = REPO / os.environ.get("CARGO_TARGET_DIR", "target")


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    return REPO


def debug_binary(name: str, package: str) -> str:
    """Path of the debug binary `name` of cargo package `package`, built if missing."""
    exe = TARGET / "debug" / name
    if not exe.exists():
        subprocess.run(["cargo", "build", "-p", package], cwd=REPO, check=True)
    return str(exe)


@pytest.fixture(scope="session")
def sadesim() -> str:
    """Path of the debug `sadesim` binary, built if missing."""
    return debug_binary("sadesim", "sadesim")


@pytest.fixture(scope="session")
def sadesim_operator() -> str:
    """Path of the debug `sadesim-operator` binary (the chart's image), built if missing."""
    return debug_binary("sadesim-operator", "sadesim-operator")


@pytest.fixture(scope="session")
def sim_worker() -> str:
    """Path of the debug `sim-worker` binary, built if missing."""
    return debug_binary("sim-worker", "sim-worker")


@pytest.fixture(scope="session")
def venv_bin() -> pathlib.Path:
    return pathlib.Path(os.environ.get("VIRTUAL_ENV", REPO / ".venv")) / "bin"


@pytest.fixture(scope="session")
def start_run(sadesim, tmp_path_factory):
    """`start_run(doc, *args)` -> a `simrun.SimRun` context manager for the SimulationRun
    `doc`: `sadesim run --no-pilot [args]` in a fresh temporary folder, stopped with SIGINT on
    exit.

    The MAVLink ports are fixed, so use it from module-scoped fixtures and never run the
    interop tests in parallel (no `pytest -n`) or beside another run that uses MAVLink.
    """
    from simrun import SimRun

    def start(doc, *args):
        return SimRun(sadesim, tmp_path_factory.mktemp(doc["metadata"]["name"]), doc, args)

    return start
