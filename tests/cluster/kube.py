"""kubectl against the test cluster (tests/cluster/up.sh), as a user would drive it."""
from __future__ import annotations

import json
import subprocess
import time
from typing import Any, Callable


class Kubectl:
    """The cluster's kubectl with its admin kubeconfig."""

    def __init__(self, kubectl: str, kubeconfig: str):
        self.kubectl = kubectl
        self.kubeconfig = kubeconfig

    def run(self, *args: str, input: str | None = None, check: bool = True) -> subprocess.CompletedProcess:
        """`kubectl ARGS`; with `check`, a failure raises naming the command and its stderr."""
        result = subprocess.run(
            [self.kubectl, f"--kubeconfig={self.kubeconfig}", *args],
            input=input, capture_output=True, text=True, timeout=120,
        )
        if check and result.returncode != 0:
            raise AssertionError(f"kubectl {' '.join(args)} failed ({result.returncode}): {result.stderr.strip()}")
        return result

    def json(self, *args: str) -> Any:
        """`kubectl get ARGS -o json`, parsed."""
        return json.loads(self.run("get", *args, "-o", "json").stdout)

    def exists(self, *args: str) -> bool:
        return self.run("get", *args, check=False).returncode == 0


def wait_for(what: str, seconds: float, probe: Callable[[], Any], every: float = 1.0) -> Any:
    """Calls `probe` until it returns something true and returns that; after `seconds` fails
    naming `what` and the last value (or exception) seen."""
    deadline = time.monotonic() + seconds
    last: Any = None
    while True:
        try:
            last = probe()
            if last:
                return last
        except AssertionError as e:  # a kubectl that failed: try again until the deadline
            last = e
        if time.monotonic() >= deadline:
            raise AssertionError(f"{what}: not after {seconds:.0f} s (last: {last!r})")
        time.sleep(every)


def phase(kubectl: Kubectl, namespace: str, name: str) -> str:
    """The SimulationRun's `status.phase` ('' before the operator wrote one)."""
    return kubectl.json("simulationrun", name, "-n", namespace).get("status", {}).get("phase", "")


def wait_phase(kubectl: Kubectl, namespace: str, name: str, phases: set, seconds: float = 240) -> dict:
    """Waits until the run is in one of `phases`; the run then."""
    wait_for(f"{name} in {sorted(phases)}", seconds, lambda: phase(kubectl, namespace, name) in phases, every=2)
    return kubectl.json("simulationrun", name, "-n", namespace)


def condition(obj: dict, kind: str) -> dict | None:
    """The status condition of type `kind`, or None."""
    return next((c for c in obj.get("status", {}).get("conditions", []) if c.get("type") == kind), None)
