"""What only a real API server can say: the CRD as kube-apiserver takes it (structural
schema, CEL rules within their cost budget), every scenario of the repository through
server-side dry-run, spec immutability on update, and the operator's Valid=False for what the
schema cannot express."""
import json
import pathlib
import re
import time

import pytest
import yaml

from conftest import quickstart
from kube import condition, wait_for, wait_phase

REPO = pathlib.Path(__file__).resolve().parents[2]

VALID = sorted(REPO.glob("examples/*.yaml")) + sorted(REPO.glob("examples/maps/*.yaml")) \
    + sorted((REPO / "tests/scenarios/valid").iterdir())
INVALID = sorted((REPO / "tests/scenarios/invalid").iterdir())

# Which layer refuses each invalid scenario of tests/scenarios/invalid (its `# expect:` line
# names the field paths). "client": kubectl itself (the document cannot be sent as JSON);
# "apiserver": `kubectl apply --dry-run=server` fails (OpenAPI schema, CEL rules, metadata);
# "operator": the API server stores the run and the operator sets Valid=False naming the
# path (what needs the planner: geometry, cross-references, world bounds).
REFUSED_BY = {
    "infinity.yaml": "client",
    "nan.yaml": "client",
    "airframe-unknown.yaml": "operator",
    "criterion-landed-near-unknown-marker.yaml": "operator",
    "criterion-unknown-group.yaml": "operator",
    "criterion-unknown-zone.yaml": "operator",
    "duration-negative.yaml": "operator",
    "duration-zero.yaml": "operator",
    "gnss-dropout-unknown-group.yaml": "operator",
    "home-outside-world.yaml": "operator",
    "mission-waypoint-above-max-altitude.yaml": "operator",
    "mission-without-takeoff.yaml": "operator",
    "pilot-env-reserved.yaml": "operator",
    "polygon-self-intersecting.yaml": "operator",
    "total-drones-over-max.yaml": "operator",
    "zone-active-after-run.yaml": "operator",
    "zone-vertex-outside-world.yaml": "operator",
}
# Every other invalid scenario: the API server.


def expected_paths(path: pathlib.Path) -> list:
    first = path.read_text().splitlines()[0]
    match = re.match(r"#\s*expect:\s*(.*)", first)
    assert match, f"{path.name}: first line is not '# expect: <field paths>'"
    return match.group(1).split()


def test_the_crd_is_structural_and_established(crd):
    conditions = {c["type"]: c["status"] for c in crd["status"]["conditions"]}
    assert conditions.get("Established") == "True", conditions
    assert conditions.get("NamesAccepted") == "True", conditions
    assert "NonStructuralSchema" not in conditions, conditions
    assert crd["status"]["acceptedNames"]["shortNames"], "kubectl get simrun needs the short names"


def in_namespace(path: pathlib.Path, namespace: str) -> str:
    """The document(s) at `path` as JSON, moved to `namespace` (some name their own)."""
    docs = [d for d in yaml.safe_load_all(path.read_text()) if d is not None]
    for doc in docs:
        for item in doc["items"] if doc.get("kind") == "List" else [doc]:
            item.setdefault("metadata", {})["namespace"] = namespace
    return json.dumps({"apiVersion": "v1", "kind": "List", "items": docs} if len(docs) > 1 else docs[0],
                      allow_nan=False)


@pytest.fixture(scope="module")
def dry_run_namespace(kubectl):
    """One namespace for every dry run (a dry run stores nothing)."""
    kubectl.run("create", "namespace", "dry-run")
    yield "dry-run"
    kubectl.run("delete", "namespace", "dry-run", "--wait=false")


@pytest.mark.parametrize("path", VALID, ids=lambda p: str(p.relative_to(REPO)))
def test_valid_scenarios_pass_server_side_dry_run(kubectl, crd, dry_run_namespace, path):
    result = kubectl.run("apply", "--dry-run=server", "-f", "-", "-o", "name", check=False,
                         input=in_namespace(path, dry_run_namespace))
    assert result.returncode == 0, result.stderr
    assert "simulationrun.sadesim.io/" in result.stdout
    # Nothing was stored.
    assert kubectl.json("simulationruns", "-n", dry_run_namespace)["items"] == []


def refusal(kubectl, namespace, path) -> tuple:
    """(layer, message): which layer refused the invalid scenario at `path`, and what it said."""
    try:
        document = in_namespace(path, namespace)
    except ValueError as e:  # NaN and infinities have no JSON form: kubectl cannot send them
        result = kubectl.run("apply", "--dry-run=server", "-n", namespace, "-f", str(path), check=False)
        assert result.returncode != 0, f"kubectl sent {path.name}: {result.stdout}"
        return "client", f"{result.stderr} ({e})"
    result = kubectl.run("apply", "--dry-run=server", "-f", "-", input=document, check=False)
    if result.returncode != 0:
        return "apiserver", result.stderr
    # Stored as it is: the operator must refuse it with Valid=False and no children.
    kubectl.run("apply", "-f", "-", input=document)
    name = json.loads(document)["metadata"]["name"]

    def invalid():
        run = kubectl.json("simulationrun", name, "-n", namespace)
        valid = condition(run, "Valid")
        return valid if valid and valid["status"] == "False" else None

    valid = wait_for(f"{name}: Valid=False from the operator", 60, invalid)
    run = kubectl.json("simulationrun", name, "-n", namespace)
    assert run["status"]["phase"] == "Failed", run["status"]
    pods = kubectl.json("pods", "-n", namespace)["items"]
    assert pods == [], f"an invalid run made pods: {[p['metadata']['name'] for p in pods]}"
    return "operator", valid["message"]


@pytest.mark.parametrize("path", INVALID, ids=lambda p: p.name)
def test_invalid_scenarios_are_refused_naming_the_field(kubectl, operator, namespace, path):
    layer, message = refusal(kubectl, namespace, path)
    print(f"{path.name}: refused by {layer}: {message.strip()}")
    paths = expected_paths(path)
    assert layer == REFUSED_BY.get(path.name, "apiserver"), f"{path.name} refused by {layer}: {message}"
    named = [p for p in paths if names(message, p)]
    if layer == "client":
        # kubectl names the file and the value it cannot encode, not the field (`sadesim
        # validate` does: tests/interop/test_broken_inputs.py); nothing reaches the cluster.
        assert path.name in message and "unsupported value" in message, message
        return
    if layer == "operator":
        # The operator's validator lists every problem of the run in one pass.
        assert named == paths, f"{path.name}: the operator's Valid=False names {named} of {paths}: {message}"
    else:
        # The API server stops at what its schema and rules see (multi-error.yaml has
        # problems only the planner finds): it must name at least one of the fields.
        assert named, f"{path.name}: the {layer}'s refusal names none of {paths}: {message}"


def names(message: str, path: str) -> bool:
    """Whether `message` names the field `path` (`spec.fleet[1].name`): the path itself, or,
    for a duplicate key of a list map, the list item and the key (`spec.fleet[1]: Duplicate
    value: {"name":...}`)."""
    if path in message:
        return True
    parent, _, key = path.rpartition(".")
    return f'{parent}: Duplicate value: {{"{key}":' in message


def test_spec_is_immutable_but_abort(kubectl, crd, namespace):
    """The CRD's transition rules (CEL) as the API server enforces them on update."""
    run = quickstart()
    name = run["metadata"]["name"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=yaml.safe_dump(run))
    for patch, field in [
        ({"spec": {"duration": "7m"}}, "spec.duration"),
        ({"spec": {"fleet": [{**run["spec"]["fleet"][0], "count": run["spec"]["fleet"][0]["count"] + 1}]}}, "spec.fleet"),
        ({"spec": {"seed": 99}}, "spec.seed"),
        ({"spec": {"queue": "team-a"}}, "spec"),
    ]:
        result = kubectl.run("patch", "simulationrun", name, "-n", namespace, "--type=merge",
                             "-p", json.dumps(patch), check=False)
        assert result.returncode != 0, f"the API server took {patch}"
        assert field in result.stderr, result.stderr
        assert "only spec.abort may change" in result.stderr, result.stderr
    kubectl.run("patch", "simulationrun", name, "-n", namespace, "--type=merge", "-p", '{"spec":{"abort":true}}')
    assert kubectl.json("simulationrun", name, "-n", namespace)["spec"]["abort"] is True


CHILD_KINDS = "pods,jobs,deployments,services,configmaps,secrets,serviceaccounts,roles,rolebindings,networkpolicies"


def children(kubectl, namespace: str, run_uid: str) -> dict:
    """{kind/name: uid} of every object in `namespace` that the run owns."""
    items = kubectl.json(CHILD_KINDS, "-n", namespace)["items"]
    return {
        f"{o['kind']}/{o['metadata']['name']}": o["metadata"]["uid"]
        for o in items
        if any(r.get("uid") == run_uid for r in o["metadata"].get("ownerReferences", []))
    }


def settled(kubectl, namespace: str, name: str, quiet_s: float = 12.0) -> dict:
    """The run once the operator has made its children and stopped writing to it for
    `quiet_s` seconds (more than two of its requeue periods)."""
    def snapshot():
        run = kubectl.json("simulationrun", name, "-n", namespace)
        return run["metadata"]["resourceVersion"], run

    last_rv, run = snapshot()
    quiet_since = time.monotonic()
    deadline = quiet_since + 120
    while time.monotonic() - quiet_since < quiet_s:
        assert time.monotonic() < deadline, f"{name} never settled: status {run.get('status')}"
        time.sleep(1)
        rv, run = snapshot()
        if rv != last_rv:
            last_rv, quiet_since = rv, time.monotonic()
    return run


@pytest.mark.parametrize("apply", [
    pytest.param(["apply"], id="client-side-apply (Argo CD)"),
    pytest.param(["apply", "--server-side", "--field-manager=kustomize-controller"], id="server-side-apply (Flux)"),
])
def test_reapplying_an_unchanged_run_changes_nothing(kubectl, operator, namespace, apply):
    """What Argo CD and Flux do every few minutes: the same document again, while the run
    flies and after it ended, must not bump the generation, re-create a child, restart the
    run or (once it ended) make the operator write it again."""
    run = quickstart(realtime_s=600)
    name = run["metadata"]["name"]
    document = yaml.safe_dump(run)
    kubectl.run(*apply, "-n", namespace, "-f", "-", input=document)
    wait_phase(kubectl, namespace, name, {"Running"}, 180)
    before = kubectl.json("simulationrun", name, "-n", namespace)
    owned = children(kubectl, namespace, before["metadata"]["uid"])
    assert any(k.startswith("Pod/") for k in owned), owned

    # (Client-side apply prints "configured" here although nothing is written: the API
    # server's defaults inside spec.fleet's items make kubectl send the whole list again,
    # which the API server finds equal and does not store.)
    for _ in range(2):
        kubectl.run(*apply, "-n", namespace, "-f", "-", input=document)
    time.sleep(12)  # more than two of the operator's requeue periods
    during = kubectl.json("simulationrun", name, "-n", namespace)
    assert during["metadata"]["generation"] == before["metadata"]["generation"]
    assert during["metadata"].get("annotations") == before["metadata"].get("annotations")
    assert during["status"]["phase"] == "Running", during["status"]
    assert during["status"]["observedGeneration"] == before["metadata"]["generation"]
    now_owned = children(kubectl, namespace, during["metadata"]["uid"])
    assert {k: now_owned.get(k) for k in owned} == owned, "a child was re-created"

    # Ended (spec.abort, the one field that may change), then re-applied: nothing moves.
    kubectl.run("patch", "simulationrun", name, "-n", namespace, "--type=merge", "-p", '{"spec":{"abort":true}}')
    wait_phase(kubectl, namespace, name, {"Aborted"}, 120)
    ended = settled(kubectl, namespace, name)
    for _ in range(2):
        kubectl.run(*apply, "-n", namespace, "-f", "-", input=document)
    after = settled(kubectl, namespace, name)
    assert after["metadata"]["generation"] == ended["metadata"]["generation"]
    assert after["metadata"]["resourceVersion"] == ended["metadata"]["resourceVersion"], \
        f"the ended run was written again: {ended.get('status')} -> {after.get('status')}"
    assert after["spec"].get("abort") is True, "the re-apply took back spec.abort"
