"""Faults on the real cluster, with the chart's operator and the cluster's object store:
nothing a run wrote is lost, and its status says what happened."""
import os
import pathlib
import subprocess

import pytest
import yaml

from conftest import quickstart
from kube import condition, phase, wait_for, wait_phase

REPO = pathlib.Path(__file__).resolve().parents[2]
SADESIM = REPO / os.environ.get("CARGO_TARGET_DIR", "target") / "debug" / "sadesim"
# The object store as this machine reaches it (tests/cluster/objectstore.sh).
STORE_ENV = {
    "AWS_ACCESS_KEY_ID": "sadesim", "AWS_SECRET_ACCESS_KEY": "sadesim-e2e-secret", "AWS_REGION": "us-east-1",
    "AWS_ENDPOINT_URL": "http://127.0.0.1:9000", "AWS_ALLOW_HTTP": "true",
}


def realtime_run(seconds: int) -> tuple:
    """(name, document): the quickstart at real time for `seconds`."""
    run = quickstart(realtime_s=seconds)
    return run["metadata"]["name"], yaml.safe_dump(run)


def get_run(kubectl, namespace, name):
    return kubectl.json("simulationrun", name, "-n", namespace)


def verify_archive(url: str) -> str:
    """`sadesim archive verify` of the archived run at `url`, from this machine."""
    assert url.startswith("s3://"), url
    result = subprocess.run([str(SADESIM), "archive", "verify", url], capture_output=True, text=True,
                            env=dict(os.environ, **STORE_ENV), timeout=120)
    assert result.returncode == 0, f"archive verify {url}: {result.stdout}{result.stderr}"
    return result.stdout


def pods_of(kubectl, namespace, name, role=None) -> list:
    selector = f"sadesim.io/run={name}" + (f",sadesim.io/role={role}" if role else "")
    return kubectl.json("pods", "-n", namespace, "-l", selector)["items"]


def test_the_operator_pod_deleted_mid_run(kubectl, operator, namespace):
    """The run goes on without the operator and finishes; the new operator pod catches up."""
    name, document = realtime_run(40)
    kubectl.run("apply", "-n", namespace, "-f", "-", input=document)
    wait_phase(kubectl, namespace, name, {"Running"})
    coordinator = pods_of(kubectl, namespace, name, "coordinator")[0]["metadata"]["uid"]
    old = kubectl.json("pods", "-n", operator, "-l", "app.kubernetes.io/name=sadesim")["items"]
    kubectl.run("delete", "pod", "-n", operator, *[p["metadata"]["name"] for p in old], "--wait=false")
    kubectl.run("rollout", "status", "-n", operator, "deployment/sadesim", "--timeout=120s")
    # The run went on meanwhile: the same coordinator, still Running.
    assert phase(kubectl, namespace, name) == "Running"
    assert pods_of(kubectl, namespace, name, "coordinator")[0]["metadata"]["uid"] == coordinator
    run = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"})
    assert run["status"]["phase"] == "Succeeded", run["status"]
    assert run["status"]["simTimeS"] == pytest.approx(40, abs=0.5)
    new = kubectl.json("pods", "-n", operator, "-l", "app.kubernetes.io/name=sadesim")["items"]
    assert {p["metadata"]["uid"] for p in new}.isdisjoint({p["metadata"]["uid"] for p in old})
    print(verify_archive(run["status"]["archive"]["url"]))


def test_a_shard_pod_deleted_mid_run(kubectl, operator, namespace):
    """The run fails naming the shard; what was written so far is archived and verifies."""
    name, document = realtime_run(120)
    kubectl.run("apply", "-n", namespace, "-f", "-", input=document)
    wait_phase(kubectl, namespace, name, {"Running"})
    wait_for(f"{name} past 5 s", 60, lambda: get_run(kubectl, namespace, name)["status"].get("simTimeS", 0) >= 5)
    shard = pods_of(kubectl, namespace, name, "shard")[0]["metadata"]["name"]
    kubectl.run("delete", "pod", "-n", namespace, shard, "--wait=false")
    run = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"})
    status = run["status"]
    assert status["phase"] == "Failed", status
    assert "shard" in status["message"], status["message"]
    assert status["simTimeS"] < 120, status
    print(status["message"])
    print(verify_archive(status["archive"]["url"]))


def test_a_run_deleted_mid_flight(kubectl, operator, namespace):
    """The finalizer archives what exists, then every child is gone, then the run."""
    name, document = realtime_run(120)
    kubectl.run("apply", "-n", namespace, "-f", "-", input=document)
    wait_phase(kubectl, namespace, name, {"Running"})
    wait_for(f"{name} past 5 s", 60, lambda: get_run(kubectl, namespace, name)["status"].get("simTimeS", 0) >= 5)
    uid = get_run(kubectl, namespace, name)["metadata"]["uid"]
    kubectl.run("delete", "simulationrun", name, "-n", namespace, "--wait=false")
    wait_for(f"{name} gone", 180, lambda: not kubectl.exists("simulationrun", name, "-n", namespace), every=2)
    kinds = "pods,jobs,services,configmaps,deployments,networkpolicies"
    left = kubectl.json(kinds, "-n", namespace, "-l", f"sadesim.io/run={name}")["items"]
    # Whatever is left is already being deleted (a pod stopping), and is gone soon after.
    alive = [f"{o['kind']}/{o['metadata']['name']}" for o in left if not o["metadata"].get("deletionTimestamp")]
    assert alive == [], f"children outlived their run: {alive}"
    wait_for("every child gone", 60,
             lambda: kubectl.json(kinds, "-n", namespace, "-l", f"sadesim.io/run={name}")["items"] == [])
    print(verify_archive(f"s3://sadesim-runs/{namespace}/{name}/{uid}/"))


def test_the_object_store_unreachable_at_archive_time(kubectl, operator, namespace):
    """Archiving retries with backoff under a condition that says why, the run is not
    Succeeded while its archive is missing, and it completes once the store is back."""
    store = str(REPO / "tests/cluster/objectstore.sh")
    name, document = realtime_run(20)
    kubectl.run("apply", "-n", namespace, "-f", "-", input=document)
    wait_phase(kubectl, namespace, name, {"Running"})
    subprocess.run([store, "stop"], check=True)
    try:
        def archive_failing():
            run = get_run(kubectl, namespace, name)
            archived = condition(run, "Archived")
            return run if archived and archived["status"] == "False" and archived["reason"] == "ArchiveFailed" else None

        run = wait_for(f"{name}: Archived=False (ArchiveFailed)", 180, archive_failing, every=2)
        assert run["status"]["phase"] == "Archiving", run["status"]
        print(condition(run, "Archived")["message"])
    finally:
        subprocess.run([store, "resume"], check=True)
    run = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"}, seconds=300)
    assert run["status"]["phase"] == "Succeeded", run["status"]
    print(verify_archive(run["status"]["archive"]["url"]))
