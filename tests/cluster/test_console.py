"""The web console on the real cluster (chart value console.enabled): it acts with each
user's own Kubernetes identity. A user's token with rights in a namespace launches a run
there that kubectl sees, watches it and stops it; the same token in a namespace where it
has no rights, or no token at all, gets the API server's refusal, passed through as it is.
The console's own ServiceAccount is bound to no role."""
import json
import subprocess
import urllib.error
import urllib.request

import pytest

from conftest import REPO, SYSTEM_NS, quickstart
from kube import wait_for


def call(base: str, method: str, path: str, body=None, token: str | None = None, timeout: float = 30):
    """(status, JSON body) of one API call."""
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(base + path, data=data, method=method)
    request.add_header("Content-Type", "application/json")
    if token:
        request.add_header("Authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(request, timeout=timeout) as response:
            return response.status, json.loads(response.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


@pytest.fixture(scope="module")
def console(kubectl, operator) -> str:
    """The chart's console pod, reached at its pod IP from this machine (the node)."""
    kubectl.run("rollout", "status", "deployment/sadesim-console", "-n", SYSTEM_NS, "--timeout=120s")
    pods = kubectl.json("pods", "-n", SYSTEM_NS, "-l", "app.kubernetes.io/component=console")["items"]
    ip = next(p["status"]["podIP"] for p in pods if p["status"].get("podIP"))
    base = f"http://{ip}:8400"
    wait_for("the console answers", 60, lambda: call(base, "GET", "/api/info")[0] == 200)
    return base


def user_with_rights_in(kubectl, namespace: str, name: str = "alice") -> str:
    """A ServiceAccount bound to Roles that may create, read, watch and patch SimulationRuns
    and list Events in `namespace` only; its token."""
    kubectl.run("create", "serviceaccount", name, "-n", namespace)
    kubectl.run("create", "role", "run-editor", "-n", namespace,
                "--verb=create,get,list,watch,patch", "--resource=simulationruns.sadesim.io")
    kubectl.run("create", "role", "event-reader", "-n", namespace, "--verb=list", "--resource=events")
    for role in ["run-editor", "event-reader"]:
        kubectl.run("create", "rolebinding", f"{name}-{role}", "-n", namespace, f"--role={role}",
                    f"--serviceaccount={namespace}:{name}")
    return kubectl.run("create", "token", name, "-n", namespace, "--duration=1h").stdout.strip()


def test_the_console_s_own_account_is_bound_to_no_role(kubectl, console):
    account = f"system:serviceaccount:{SYSTEM_NS}:sadesim-console"
    for verb, resource in [("list", "simulationruns.sadesim.io"), ("create", "simulationruns.sadesim.io"),
                           ("list", "secrets"), ("list", "namespaces")]:
        allowed = kubectl.run("auth", "can-i", verb, resource, "--all-namespaces", f"--as={account}", check=False)
        assert allowed.stdout.strip() == "no", f"the console's ServiceAccount may {verb} {resource}"


def test_a_user_launches_watches_and_stops_a_run_with_their_own_identity(kubectl, console, namespace):
    token = user_with_rights_in(kubectl, namespace)
    status, info = call(console, "GET", "/api/info")
    assert status == 200 and info["backend"] == "cluster" and info["needsToken"] is True

    run = quickstart(realtime_s=600)
    run["metadata"]["name"] = "from-the-console"
    status, body = call(console, "POST", "/api/runs", {"document": run, "namespace": namespace}, token)
    assert status == 201, body
    assert body["run"]["id"] == f"{namespace}.from-the-console"
    # kubectl sees the run the console created, as created by the user (managedFields).
    created = kubectl.json("simulationrun", "from-the-console", "-n", namespace)
    assert created["spec"]["fleet"][0]["count"] == run["spec"]["fleet"][0]["count"]

    status, body = call(console, "GET", f"/api/runs?namespace={namespace}", token=token)
    assert status == 200 and [r["name"] for r in body["runs"]] == ["from-the-console"]
    # The watch stream: its first event is the list, pushed by the API server's watch.
    request = urllib.request.Request(f"{console}/api/runs/watch?namespace={namespace}")
    request.add_header("Authorization", f"Bearer {token}")
    with urllib.request.urlopen(request, timeout=30) as stream:
        lines = []
        while not any(line.startswith("data:") for line in lines):
            lines.append(stream.readline().decode().strip())
    first = json.loads(next(line for line in lines if line.startswith("data:"))[5:])
    assert [r["id"] for r in first["runs"]] == [f"{namespace}.from-the-console"]

    wait_for("the run flies", 240, lambda: call(console, "GET", f"/api/runs/{namespace}.from-the-console", token=token)[1]["run"]["phase"] == "Running", every=2)
    status, body = call(console, "POST", f"/api/runs/{namespace}.from-the-console/stop", {}, token)
    assert status == 202, body
    assert kubectl.json("simulationrun", "from-the-console", "-n", namespace)["spec"]["abort"] is True
    wait_for("the stopped run ends", 240, lambda: call(console, "GET", f"/api/runs/{namespace}.from-the-console", token=token)[1]["run"]["phase"] == "Aborted", every=2)


def test_the_api_server_s_refusals_reach_the_user_unchanged(kubectl, console, namespace):
    token = user_with_rights_in(kubectl, namespace, "bob")
    other = f"{namespace}-other"
    kubectl.run("create", "namespace", other)
    kubectl.run("label", "namespace", other, "sadesim-test=true")
    try:
        run = quickstart()
        status, body = call(console, "POST", "/api/runs", {"document": run, "namespace": other}, token)
        assert status == 403, body
        assert "forbidden" in body["error"] and f"system:serviceaccount:{namespace}:bob" in body["error"], body
        assert not kubectl.json("simulationruns", "-n", other)["items"]
        status, body = call(console, "GET", f"/api/runs?namespace={other}", token=token)
        assert status == 403 and "cannot list resource" in body["error"], body
        # No token: the console does not fall back on an identity of its own.
        status, body = call(console, "POST", "/api/runs", {"document": run, "namespace": namespace})
        assert status == 401, body
        status, body = call(console, "GET", "/api/runs", token="not-a-token")
        assert status == 401, body
    finally:
        kubectl.run("delete", "namespace", other, "--wait=false", check=False)


def test_a_finished_run_s_criteria_and_archive_are_read_as_the_user(kubectl, console, namespace):
    token = user_with_rights_in(kubectl, namespace, "carol")
    run = quickstart()
    run["metadata"]["name"] = "archived"
    status, body = call(console, "POST", "/api/runs", {"document": run, "namespace": namespace}, token)
    assert status == 201, body
    rid = f"{namespace}.archived"
    wait_for("the run succeeds", 300,
             lambda: call(console, "GET", f"/api/runs/{rid}", token=token)[1]["run"]["phase"] in ("Succeeded", "Failed"), every=3)
    status, detail = call(console, "GET", f"/api/runs/{rid}", token=token)
    assert detail["run"]["phase"] == "Succeeded" and detail["run"]["verdict"] == "passed", detail["run"]
    # Each criterion as judged, from the run's summary.json in the object store.
    assert [(c["name"], c["state"]) for c in detail["criteria"]] == [
        ("spec.criteria[0]: noCrashes", "passed"), ("spec.criteria[1]: altitudeLimitsRespected", "passed")], detail["criteria"]
    status, archive = call(console, "GET", f"/api/archive?namespace={namespace}", token=token)
    assert status == 200 and [e["id"] for e in archive["runs"]] == [rid], archive
    assert archive["runs"][0]["complete"] and archive["runs"][0]["verdict"] == "passed"
    status, verified = call(console, "POST", f"/api/archive/{rid}/verify", {}, token)
    assert status == 200 and verified["ok"] and verified["checked"] > 10, verified
    # The archive of a run is read only for a user who may get the run.
    status, body = call(console, "POST", f"/api/archive/{rid}/verify", {})
    assert status == 401, body


def test_in_the_page_a_launch_reaches_kubectl_and_a_refusal_reaches_the_user(kubectl, console, namespace, tmp_path):
    """As a person: the token pasted into the page, the quickstart launched into the user's
    namespace (kubectl sees the SimulationRun), then into one where the user has no rights:
    the page shows the API server's refusal."""
    token = user_with_rights_in(kubectl, namespace, "dave")
    forbidden = f"{namespace}-x"
    config = tmp_path / "cluster.json"
    config.write_text(json.dumps({
        "url": console + "/", "outDir": str(tmp_path), "scenario": "cluster", "allowHosts": [console.split("//")[1].split(":")[0]],
        "token": token, "namespace": namespace, "forbidden": forbidden, "file": str(REPO / "examples/quickstart.yaml"),
        "allowHttpErrors": [401, 403]}))
    done = subprocess.run(["node", str(REPO / "tests/browser/console.mjs"), str(config)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"the browser driver failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["failure"] is None and report["errors"] == [] and report["external"] == [], report
    assert report["result"]["launched"] == f"#/runs/{namespace}.quickstart", report["result"]
    assert kubectl.json("simulationrun", "quickstart", "-n", namespace)["metadata"]["name"] == "quickstart"
    refusal = report["result"]["refusal"]
    assert "forbidden" in refusal and f"system:serviceaccount:{namespace}:dave" in refusal and forbidden in refusal, refusal


def test_a_cluster_run_s_live_view_is_refused_as_not_supported_saying_how_to_reach_it(kubectl, console, namespace):
    token = user_with_rights_in(kubectl, namespace, "erin")
    run = quickstart(realtime_s=300)
    run["metadata"]["name"] = "watched"
    run["spec"]["rendering"] = {"enabled": True}
    status, body = call(console, "POST", "/api/runs", {"document": run, "namespace": namespace}, token)
    assert status == 201, body
    rid = f"{namespace}.watched"
    status, detail = call(console, "GET", f"/api/runs/{rid}", token=token)
    assert status == 200 and detail["viewUrl"] is None and detail["cameras"] == []
    status, body = call(console, "GET", f"/api/runs/{rid}/view/", token=token)
    assert status == 501 and "port-forward svc/watched-renderer" in body["error"], body
    call(console, "POST", f"/api/runs/{rid}/stop", {}, token)
