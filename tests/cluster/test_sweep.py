"""A SimulationSweep on the real cluster: the operator creates the sweep's runs, never more
in flight than `parallelism`, owned by the sweep; their phases and verdicts reach the
sweep's status; re-applying the sweep creates nothing; deleting it deletes its runs."""
import time

import yaml

from conftest import BUCKET, quickstart
from kube import wait_for

TERMINAL = {"Succeeded", "Failed", "Aborted"}


def sweep_document() -> dict:
    """examples/quickstart.yaml's run at two cruise speeds, one run each, one at a time,
    archived to the cluster's object store."""
    base = quickstart()["spec"]
    base["archive"] = {"url": f"s3://{BUCKET}"}
    return {
        "apiVersion": "sadesim.io/v1alpha1",
        "kind": "SimulationSweep",
        "metadata": {"name": "qs-speed"},
        "spec": {
            "base": {"spec": base},
            "parameters": [{"name": "speed", "field": "spec.fleet[0].mission.speedMps", "values": [6, 8]}],
            "repetitions": 1,
            "parallelism": 1,
        },
    }


def test_a_small_sweep_runs_end_to_end(kubectl, operator, namespace):
    document = yaml.safe_dump(sweep_document())
    kubectl.run("apply", "-n", namespace, "-f", "-", input=document)

    most_in_flight = 0

    def completed():
        nonlocal most_in_flight
        runs = kubectl.json("simulationruns", "-n", namespace, "-l", "sadesim.io/sweep=qs-speed")["items"]
        in_flight = [r for r in runs if (r.get("status") or {}).get("phase") not in TERMINAL]
        most_in_flight = max(most_in_flight, len(in_flight))
        sweep = kubectl.json("simulationsweep", "qs-speed", "-n", namespace)
        return sweep if (sweep.get("status") or {}).get("phase") == "Completed" else None

    sweep = wait_for("the sweep Completed", 900, completed, every=2)
    assert most_in_flight == 1, f"parallelism 1, but {most_in_flight} runs were in flight at once"

    runs = kubectl.json("simulationruns", "-n", namespace, "-l", "sadesim.io/sweep=qs-speed")["items"]
    names = sorted(r["metadata"]["name"] for r in runs)
    assert names == ["qs-speed-c0-r0", "qs-speed-c1-r0"], names
    speeds = {r["metadata"]["name"]: r["spec"]["fleet"][0]["mission"]["speedMps"] for r in runs}
    assert speeds == {"qs-speed-c0-r0": 6, "qs-speed-c1-r0": 8}, speeds
    for r in runs:
        owner = r["metadata"]["ownerReferences"][0]
        assert (owner["kind"], owner["name"], owner["uid"]) == ("SimulationSweep", "qs-speed", sweep["metadata"]["uid"])
        assert owner["controller"] is True and owner["blockOwnerDeletion"] is True, owner

    # The status is the runs' phases and verdicts.
    status = sweep["status"]
    passed = sum(1 for r in runs if r["status"]["phase"] == "Succeeded")
    assert (status["runs"], status["finished"], status["passed"]) == (2, 2, passed), status
    assert [c["label"] for c in status["cells"]] == ["speed=6", "speed=8"], status["cells"]
    assert sum(c["passed"] for c in status["cells"]) == passed, status["cells"]
    assert passed == 2, [r["status"] for r in runs]
    # The report, beside the runs' archives.
    assert status.get("report") == f"s3://{BUCKET}/{namespace}/qs-speed", status
    reported = next(c for c in status["conditions"] if c["type"] == "Reported")
    assert reported["status"] == "True", reported

    # GitOps: the same document again creates nothing and changes nothing.
    generation = sweep["metadata"]["generation"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=document)
    time.sleep(8)
    again = kubectl.json("simulationruns", "-n", namespace, "-l", "sadesim.io/sweep=qs-speed")["items"]
    assert sorted(r["metadata"]["uid"] for r in again) == sorted(r["metadata"]["uid"] for r in runs)
    assert kubectl.json("simulationsweep", "qs-speed", "-n", namespace)["metadata"]["generation"] == generation

    # Deleting the sweep deletes its runs (the garbage collector, through their owner
    # reference; each run's finalizer archives it first).
    kubectl.run("delete", "simulationsweep", "qs-speed", "-n", namespace, "--wait=false")
    wait_for("the sweep's runs deleted", 300,
             lambda: kubectl.json("simulationruns", "-n", namespace)["items"] == [], every=2)
