"""A pilot that fails fails the run on the real cluster, as `sadesim run` does locally: a
pilot container that exits non-zero makes the SimulationRun `Failed`, its `Pilot`
condition naming the exit code and the last lines of the pilot's log; a scenario that
declares the failure expected (`spec.pilot.expectedExit: failure`) succeeds."""
import pathlib

import yaml

from kube import condition, wait_phase

REPO = pathlib.Path(__file__).resolve().parents[2]

# Like the README's precision-landing pilot on a `python3` without OpenCV: it says one
# thing, then dies on an import (exit 1, a traceback on stderr).
DIES_AT_ONCE = ["python3", "-c", "print('pilot: starting', flush=True); import cv2_not_installed"]


def failing_pilot_run(name: str, expected_exit: str | None = None) -> dict:
    """examples/quickstart-pymavlink.yaml as fast as possible, its pilot (the examples'
    image, on the node) replaced by one that exits 1 at once."""
    run = next(d for d in yaml.safe_load_all((REPO / "examples/quickstart-pymavlink.yaml").read_text()) if d)
    run["metadata"]["name"] = name
    run["spec"]["clock"] = {"mode": "asFastAsPossible"}
    run["spec"]["pilot"]["containerCommand"] = DIES_AT_ONCE
    if expected_exit:
        run["spec"]["pilot"]["expectedExit"] = expected_exit
    return run


def test_a_pilot_that_exits_1_fails_the_run_naming_its_exit_code_and_log_tail(kubectl, operator, namespace):
    run = failing_pilot_run("pilot-dies")
    name = run["metadata"]["name"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(run))
    done = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"}, seconds=420)
    status = done["status"]
    assert status["phase"] == "Failed", status
    pilot = condition(done, "Pilot")
    assert pilot and pilot["status"] == "False" and pilot["reason"] == "PilotFailed", status["conditions"]
    message = pilot["message"]
    assert message.startswith(
        "the pilot exited with code 1 before the run ended; spec.pilot.expectedExit is success"), message
    # The last lines of its log: the container's termination message (FallbackToLogsOnError).
    assert "the last lines of its log:" in message, message
    assert "pilot: starting" in message, message
    assert "ModuleNotFoundError: No module named 'cv2_not_installed'" in message, message
    assert status["message"].startswith("the pilot failed: the pilot exited with code 1"), status["message"]
    verdict = status["verdict"]
    assert verdict["passed"] is False, verdict
    assert any(f.startswith("spec.pilot.expectedExit: the pilot exited with code 1") for f in verdict["failures"]), \
        verdict
    # The Warning Event says it too.
    events = kubectl.json("events", "-n", namespace, "--field-selector", f"involvedObject.name={name}")["items"]
    warned = [e for e in events if e.get("reason") == "PilotFailed" and e.get("type") == "Warning"]
    assert warned and "exited with code 1" in warned[0]["message"], [(e.get("reason"), e.get("message"))
                                                                     for e in events]
    print(message)


def test_a_pilot_failure_declared_expected_lets_the_run_succeed(kubectl, operator, namespace):
    run = failing_pilot_run("pilot-dies-expected", expected_exit="failure")
    name = run["metadata"]["name"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(run))
    done = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"}, seconds=420)
    status = done["status"]
    pilot = condition(done, "Pilot")
    assert pilot and pilot["status"] == "True" and pilot["reason"] == "AsExpected", status.get("conditions")
    assert "exited with code 1" in pilot["message"], pilot
    assert status["phase"] == "Succeeded", status
