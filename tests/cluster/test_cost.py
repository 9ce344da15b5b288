"""What a run costs on the real cluster, measured and printed (docs/kubernetes.md and
docs/performance.md quote it): apply -> every pod Running, apply -> Succeeded for the
quickstart, and the operator's reconciles (its metrics) and API requests (the API server's
audit log of the operator's service account) for that run. The assertions are on behaviour
only; the times are measurements, never limits."""
import json
import os
import pathlib
import time

import yaml

from conftest import quickstart
from kube import wait_for

AUDIT_LOG = pathlib.Path(os.environ.get("SADESIM_CLUSTER_DIR", "/var/lib/sadesim-cluster")) / "logs" / "audit.log"


def operator_metric(kubectl, namespace: str, name: str) -> float:
    """A counter of the operator's /metrics, read through the API server's Service proxy."""
    text = kubectl.run("get", "--raw", f"/api/v1/namespaces/{namespace}/services/sadesim-metrics:metrics/proxy/metrics").stdout
    for line in text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    raise AssertionError(f"{name} not in the operator's metrics:\n{text[:2000]}")


def operator_requests(namespace: str, run_namespace: str) -> dict:
    """{verb: count} of the operator's API requests that concern `run_namespace` so far."""
    counts: dict = {}
    for line in AUDIT_LOG.read_text().splitlines():
        event = json.loads(line)
        if event.get("stage") != "ResponseComplete":
            continue
        if event["user"]["username"] != f"system:serviceaccount:{namespace}:sadesim":
            continue
        if event.get("objectRef", {}).get("namespace") != run_namespace:
            continue
        counts[event["verb"]] = counts.get(event["verb"], 0) + 1
    return counts


def test_what_the_quickstart_costs(kubectl, operator, namespace):
    run = quickstart()
    name = run["metadata"]["name"]
    reconciles_before = operator_metric(kubectl, operator, "sadesim_operator_reconciles_total")
    start = time.monotonic()
    kubectl.run("apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(run))

    def every_pod_running():
        pods = kubectl.json("pods", "-n", namespace, "-l", f"sadesim.io/run={name}")["items"]
        roles = {p["metadata"]["labels"].get("sadesim.io/role") for p in pods if p["status"].get("phase") == "Running"}
        return {"coordinator", "shard", "router"} <= roles

    wait_for(f"{name}: coordinator, shard and router pods Running", 300, every_pod_running, every=0.5)
    running_s = time.monotonic() - start

    def ended():
        status = kubectl.json("simulationrun", name, "-n", namespace).get("status", {})
        return status if status.get("phase") in ("Succeeded", "Failed", "Aborted") else None

    status = wait_for(f"{name} ended", 600, ended, every=0.5)
    succeeded_s = time.monotonic() - start
    assert status["phase"] == "Succeeded", status
    time.sleep(3)  # the audit log is written in batches
    reconciles = operator_metric(kubectl, operator, "sadesim_operator_reconciles_total") - reconciles_before
    requests = operator_requests(operator, namespace)
    assert reconciles > 0 and sum(requests.values()) > 0, (reconciles, requests)
    measured = {
        "run": name, "applyToPodsRunningS": round(running_s, 1), "applyToSucceededS": round(succeeded_s, 1),
        "simTimeS": status["simTimeS"], "operatorReconciles": reconciles,
        "operatorApiRequests": sum(requests.values()), "operatorApiRequestsByVerb": requests,
    }
    print(json.dumps(measured))
    out = os.environ.get("SADESIM_CLUSTER_MEASUREMENTS")
    if out:
        with open(out, "a") as f:
            f.write(json.dumps(measured) + "\n")
