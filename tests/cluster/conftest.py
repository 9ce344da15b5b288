"""Fixtures of the real-cluster tests. tests/cluster/lane.sh brings the cluster up and runs
them with SADESIM_CLUSTER_KUBECONFIG and SADESIM_CLUSTER_BIN set; without a cluster they
fail, saying so."""
import json
import os
import pathlib
import subprocess
import sys
import uuid

import pytest
import yaml

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from kube import Kubectl, wait_for  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
CRD = REPO / "crds" / "sadesim.io_simulationruns.yaml"


def quickstart(realtime_s: int | None = None) -> dict:
    """examples/quickstart.yaml's run; with `realtime_s`, at real time for that long."""
    run = next(d for d in yaml.safe_load_all((REPO / "examples/quickstart.yaml").read_text()) if d)
    if realtime_s is not None:
        run["spec"]["clock"] = {"mode": "realtime"}
        run["spec"]["duration"] = f"{realtime_s}s"
    return run


def required_env(name: str) -> str:
    value = os.environ.get(name)
    if not value:
        pytest.fail(f"{name} is not set: run these tests through tests/cluster/lane.sh, which brings the cluster up")
    return value


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    return REPO


@pytest.fixture(scope="session")
def kubectl() -> Kubectl:
    bin_dir = pathlib.Path(required_env("SADESIM_CLUSTER_BIN"))
    k = Kubectl(str(bin_dir / "kubectl"), required_env("SADESIM_CLUSTER_KUBECONFIG"))
    k.run("get", "--raw", "/readyz")
    return k


@pytest.fixture(scope="session")
def helm() -> str:
    exe = REPO / ".tools" / "bin" / "helm"
    assert exe.exists(), "helm is missing: run tests/install-tools.sh"
    return str(exe)


@pytest.fixture(scope="session")
def crd(kubectl):
    """The SimulationRun CRD, applied as the chart ships it and Established."""
    kubectl.run("apply", "--server-side", "--field-manager=sadesim-tests", "-f", str(CRD))

    def established():
        crd = kubectl.json("crd", "simulationruns.sadesim.io")
        # Just after the create the API server has written `status.conditions: null`.
        conditions = (crd.get("status") or {}).get("conditions") or []
        ok = any(c["type"] == "Established" and c["status"] == "True" for c in conditions)
        return crd if ok else None

    return wait_for("the CRD Established", 60, established)


SYSTEM_NS = "sadesim-system"
BUCKET = "sadesim-runs"
OBJECT_STORE_SECRET = "sadesim-object-store"


@pytest.fixture(scope="session")
def object_store(kubectl):
    """The cluster's S3 store (tests/cluster/objectstore.sh) with the runs' bucket; its URL
    inside the cluster."""
    result = subprocess.run([str(REPO / "tests/cluster/objectstore.sh"), "start", BUCKET],
                            capture_output=True, text=True, check=True)
    return result.stdout.strip()


@pytest.fixture(scope="session")
def operator(kubectl, helm, crd, object_store):
    """The operator as users install it: the chart, in sadesim-system, its pods' images the
    ones tests/cluster/lane.sh imported (tag SADESIM_CLUSTER_IMAGE_TAG), archiving every run
    to s3://sadesim-runs on the cluster's object store. Its log is printed when a test fails
    (see pytest_runtest_makereport)."""
    tag = required_env("SADESIM_CLUSTER_IMAGE_TAG")
    installed = subprocess.run([
        helm, f"--kubeconfig={kubectl.kubeconfig}", "upgrade", "--install", "sadesim", str(REPO / "charts/sadesim"),
        "-n", SYSTEM_NS, "--create-namespace", "--wait", "--timeout", "180s",
        "--set", f"image.tag={tag}", "--set", f"workerImage.tag={tag}", "--set", f"cameraImage.tag={tag}",
        "--set", f"openfoamImage.tag={tag}", "--set", "console.enabled=true",
        "--set", f"defaultArchiveUrl=s3://{BUCKET}",
        "--set", "objectStore.create=true", "--set", f"objectStore.secretName={OBJECT_STORE_SECRET}",
        "--set", "objectStore.env.AWS_ACCESS_KEY_ID=sadesim",
        "--set", "objectStore.env.AWS_SECRET_ACCESS_KEY=sadesim-e2e-secret",
        "--set", "objectStore.env.AWS_REGION=us-east-1",
        "--set", f"objectStore.env.AWS_ENDPOINT_URL={object_store}",
        "--set-string", "objectStore.env.AWS_ALLOW_HTTP=true",
    ], capture_output=True, text=True, timeout=300)
    if installed.returncode != 0:
        # A pod that never starts is most often the node's doing (disk pressure taints it).
        taints = [(n["metadata"]["name"], n["spec"].get("taints")) for n in kubectl.json("nodes")["items"]]
        pytest.fail(f"helm upgrade --install failed:\n{installed.stdout}\n{installed.stderr}\nnode taints: {taints}")
    OPERATOR_INSTALLED.append(True)
    yield SYSTEM_NS
    subprocess.run([helm, f"--kubeconfig={kubectl.kubeconfig}", "uninstall", "sadesim", "-n", SYSTEM_NS, "--wait"],
                   check=False, capture_output=True, timeout=300)


# True once the chart's operator is installed (its log goes with a failure's report).
OPERATOR_INSTALLED: list = []


@pytest.fixture(scope="session")
def test_namespaces(kubectl):
    """The namespaces the tests made (labelled sadesim-test=true); at the end of the session
    every one must be gone: a finalizer or child that blocks a namespace's deletion fails."""
    yield
    wait_for("every test namespace deleted", 180,
             lambda: kubectl.json("namespaces", "-l", "sadesim-test=true")["items"] == [], every=2)


@pytest.fixture
def namespace(kubectl, request, test_namespaces):
    """A fresh namespace for one test, deleted afterwards (test_namespaces waits for it); with
    the operator installed, the object store's Secret is copied into it, as a team would."""
    name = f"t-{request.node.name[:40].lower().replace('_', '-').strip('-')}-{uuid.uuid4().hex[:5]}"
    name = "".join(c if c.isalnum() or c == "-" else "-" for c in name)
    kubectl.run("create", "namespace", name)
    kubectl.run("label", "namespace", name, "sadesim-test=true")
    if OPERATOR_INSTALLED:
        secret = kubectl.json("secret", OBJECT_STORE_SECRET, "-n", SYSTEM_NS)
        kubectl.run("apply", "-f", "-", input=json.dumps({
            "apiVersion": "v1", "kind": "Secret", "type": "Opaque",
            "metadata": {"name": OBJECT_STORE_SECRET, "namespace": name}, "data": secret["data"]}))
    yield name
    kubectl.run("delete", "namespace", name, "--wait=false", check=False)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.when == "call" and report.failed and OPERATOR_INSTALLED:
        kubectl = item.funcargs.get("kubectl")
        if kubectl is not None:
            log = kubectl.run("logs", "-n", SYSTEM_NS, "deployment/sadesim", "--tail=40", check=False)
            report.sections.append(("operator log (last 40 lines)", log.stdout + log.stderr))
