"""The hold for the pilot on the real cluster: the pilot Job starts on the release (its
image may still be pulled then), and simulated time waits at the release for its MAVLink,
for at most `spec.pilot.connectTimeoutS`. A pilot that never connects fails the run, and
the run's status says why."""
import pathlib

import yaml

from kube import condition, wait_phase

REPO = pathlib.Path(__file__).resolve().parents[2]


def silent_pilot_run(connect_timeout_s: int) -> dict:
    """examples/quickstart-pymavlink.yaml as fast as possible, its pilot (the examples'
    image, on the node) replaced by one that never sends a MAVLink frame."""
    run = next(d for d in yaml.safe_load_all((REPO / "examples/quickstart-pymavlink.yaml").read_text()) if d)
    run["metadata"]["name"] = "silent-pilot"
    run["spec"]["clock"] = {"mode": "asFastAsPossible"}
    run["spec"]["pilot"]["containerCommand"] = ["sleep", "3600"]
    run["spec"]["pilot"]["connectTimeoutS"] = connect_timeout_s
    return run


def test_a_pilot_that_never_connects_fails_the_run_saying_so(kubectl, operator, namespace):
    run = silent_pilot_run(20)
    name = run["metadata"]["name"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(run))
    done = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"}, seconds=420)
    status = done["status"]
    assert status["phase"] == "Failed", status
    running = condition(done, "Running")
    assert running["status"] == "False" and running["reason"] == "PilotNotConnected", running
    expected = "the pilot did not connect within 20 s: no MAVLink frame reached any of the 4 drones it flies"
    assert running["message"].startswith(expected), running
    assert status["message"].startswith(expected), status
    # Simulated time stood at the release (a few seconds of GNSS fixes), far short of the
    # 6 minutes an unheld run would have flown in 20 s.
    assert status["simTimeS"] < 15, status
    # The Warning Event says it too.
    events = kubectl.json("events", "-n", namespace, "--field-selector", f"involvedObject.name={name}")["items"]
    warned = [e for e in events if e.get("reason") == "PilotNotConnected" and e.get("type") == "Warning"]
    assert warned and warned[0]["message"].startswith(expected), [(e.get("reason"), e.get("message")) for e in events]
