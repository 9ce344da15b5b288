"""What the operator creates (`sadesim manifests`) and what the Helm chart installs, against
Kubernetes' own schemas: kubernetes-validate --strict for Kubernetes 1.33 (the API version the
operator is built against, k8s-openapi feature v1_33)."""
import ast
import json
import pathlib
import re
import subprocess
import sys

import pytest
import yaml

REPO = pathlib.Path(__file__).resolve().parents[2]
KUBERNETES_VERSION = "1.33.0"
EXAMPLES = sorted(p.name for p in (REPO / "examples").glob("*.yaml"))
HELM = REPO / ".tools" / "bin" / "helm"


def kubernetes_validate(venv_bin, text):
    return subprocess.run(
        [str(venv_bin / "kubernetes-validate"), "--strict", "-k", KUBERNETES_VERSION, "-"],
        input=text,
        capture_output=True,
        text=True,
    )


def manifests(sadesim, *args):
    result = subprocess.run([sadesim, "manifests", *args], capture_output=True, text=True, cwd=REPO)
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def kinds(text):
    return [f"{d['kind']}/{d['metadata']['name']}" for d in yaml.safe_load_all(text) if d]


def helm_template(*args):
    if not HELM.exists():
        pytest.skip("helm missing: run tests/install-tools.sh")
    result = subprocess.run(
        [str(HELM), "template", "sadesim", str(REPO / "charts" / "sadesim"), "--include-crds", *args],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout


@pytest.mark.parametrize("example", EXAMPLES)
def test_manifests_of_every_example_pass_kubernetes_validate_strict(sadesim, venv_bin, example):
    text = manifests(sadesim, f"examples/{example}")
    assert len(kinds(text)) >= 8, kinds(text)
    result = kubernetes_validate(venv_bin, text)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.count("passed") == len(kinds(text)), result.stdout


def test_manifests_of_all_examples_at_once_form_one_valid_stream(sadesim, venv_bin):
    """The issue's command: `sadesim manifests examples/*.yaml | kubernetes-validate --strict -`."""
    one_by_one = [kinds(manifests(sadesim, f"examples/{e}")) for e in EXAMPLES]
    text = manifests(sadesim, *[f"examples/{e}" for e in EXAMPLES])
    assert kinds(text) == [k for ks in one_by_one for k in ks]
    result = kubernetes_validate(venv_bin, text)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.count("passed") == len(kinds(text)), result.stdout


def test_manifests_name_the_children_the_operator_creates(sadesim):
    text = manifests(sadesim, "examples/chicago-museum.yaml", "--namespace", "team-a")
    names = kinds(text)
    # 32 drones, 16 per shard: one Indexed Job of 2 pods; one router segment.
    assert "Job/chicago-museum-shard" in names
    assert "Pod/chicago-museum-router-0" in names and "Pod/chicago-museum-router-1" not in names
    job = next(d for d in yaml.safe_load_all(text) if d and d["kind"] == "Job" and d["metadata"]["name"].endswith("-shard"))
    assert job["spec"]["completions"] == 2 and job["spec"]["completionMode"] == "Indexed"
    assert all(d["metadata"]["namespace"] == "team-a" for d in yaml.safe_load_all(text) if d)
    assert "Job/chicago-museum-pilot" in names


def test_manifests_say_why_the_operator_would_refuse_a_run(sadesim, tmp_path):
    doc = yaml.safe_load((REPO / "examples" / "quickstart-pymavlink.yaml").read_text())
    del doc["spec"]["pilot"]["image"]
    scenario = tmp_path / "no-image.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    text = manifests(sadesim, str(scenario))
    assert "spec.pilot.image: required on Kubernetes" in text
    assert "Job/quickstart-pymavlink-pilot" not in kinds(text)


def test_kubernetes_validate_rejects_a_broken_manifest(sadesim, venv_bin):
    # Guards the checks above: the tool fails on an unknown field and on a wrong type.
    docs = [d for d in yaml.safe_load_all(manifests(sadesim, "examples/quickstart.yaml")) if d]
    job = next(d for d in docs if d["kind"] == "Job")
    job["spec"]["template"]["spec"]["containers"][0]["colour"] = "red"
    assert kubernetes_validate(venv_bin, yaml.safe_dump(job)).returncode != 0
    pod = next(d for d in docs if d["kind"] == "Pod")
    pod["spec"]["containers"][0]["ports"][0]["containerPort"] = "seven"
    assert kubernetes_validate(venv_bin, yaml.safe_dump(pod)).returncode != 0


@pytest.mark.parametrize(
    "values",
    [
        [],
        [
            "--set", "kueue.enabled=true",
            "--set", "defaultArchiveUrl=s3://sadesim-runs",
            "--set", "objectStore.create=true",
            "--set", "objectStore.secretName=sadesim-object-store",
            "--set", "objectStore.namespaces={team-a,team-b}",
            "--set", "objectStore.env.AWS_REGION=us-east-1",
            "--set", "routerServiceType=LoadBalancer",
        ],
    ],
    ids=["defaults", "kueue-and-object-store"],
)
def test_helm_template_passes_kubernetes_validate_strict(venv_bin, values):
    text = helm_template(*values)
    result = kubernetes_validate(venv_bin, text)
    assert result.returncode == 0, result.stdout + result.stderr
    docs = [d for d in yaml.safe_load_all(text) if d]
    assert {d["kind"] for d in docs} >= {
        "CustomResourceDefinition", "ServiceAccount", "ClusterRole", "ClusterRoleBinding", "Role", "RoleBinding",
        "Deployment", "Service",
    }


def test_the_operator_gets_the_object_store_secret_in_its_own_namespace():
    """The operator archives pod logs itself: the Secret is made in the release namespace
    too, and the operator's container takes its keys as environment variables."""
    docs = [d for d in yaml.safe_load_all(helm_template(
        "--namespace", "sadesim-system", "--set", "objectStore.create=true",
        "--set", "objectStore.secretName=store", "--set", "objectStore.namespaces={team-a}",
        "--set", "objectStore.env.AWS_REGION=us-east-1")) if d]
    secrets = sorted(d["metadata"]["namespace"] for d in docs if d["kind"] == "Secret")
    assert secrets == ["sadesim-system", "team-a"]
    deployment = next(d for d in docs if d["kind"] == "Deployment")
    assert deployment["spec"]["template"]["spec"]["containers"][0]["envFrom"] == [{"secretRef": {"name": "store"}}]
    plain = next(d for d in yaml.safe_load_all(helm_template()) if d and d["kind"] == "Deployment")
    assert "envFrom" not in plain["spec"]["template"]["spec"]["containers"][0]


def test_the_chart_configures_the_operator_with_the_contract_env_only():
    docs = [d for d in yaml.safe_load_all(helm_template("--set", "kueue.enabled=true")) if d]
    deployment = next(d for d in docs if d["kind"] == "Deployment")
    container = deployment["spec"]["template"]["spec"]["containers"][0]
    env = {e["name"]: e.get("value") for e in container["env"]}
    assert set(env) == {
        "SADESIM_WORKER_IMAGE", "SADESIM_OPENFOAM_IMAGE", "SADESIM_CAMERA_IMAGE", "SADESIM_DEFAULT_ARCHIVE_URL", "SADESIM_OBJECT_STORE_SECRET",
        "SADESIM_ROUTER_SERVICE_TYPE", "SADESIM_KUEUE", "SADESIM_MAX_CONCURRENT_RUNS", "SADESIM_METRICS_ADDR",
        "SADESIM_LEADER_ELECTION", "POD_NAMESPACE", "POD_NAME",
    }
    assert env["SADESIM_KUEUE"] == "true" and env["SADESIM_METRICS_ADDR"] == "0.0.0.0:8080"
    # The assets Job of an OpenFOAM run takes the image with OpenFOAM, same tag as the worker's.
    assert env["SADESIM_OPENFOAM_IMAGE"].startswith("ghcr.io/sadesim/sim-worker-openfoam:")
    assert env["SADESIM_OPENFOAM_IMAGE"].split(":")[1] == env["SADESIM_WORKER_IMAGE"].split(":")[1]
    # The coordinator of a run with onboard cameras takes the image with Vulkan, same tag.
    assert env["SADESIM_CAMERA_IMAGE"].startswith("ghcr.io/sadesim/sim-worker-camera:")
    assert env["SADESIM_CAMERA_IMAGE"].split(":")[1] == env["SADESIM_WORKER_IMAGE"].split(":")[1]
    # The image's entrypoint is the operator binary itself (images/operator.Dockerfile).
    assert "args" not in container and "command" not in container
    assert container["livenessProbe"]["httpGet"]["path"] == "/healthz"
    sc = container["securityContext"]
    assert sc["readOnlyRootFilesystem"] and not sc["allowPrivilegeEscalation"] and sc["capabilities"]["drop"] == ["ALL"]
    # Least privilege: no Secrets, no wildcards; Kueue Workloads only with Kueue on.
    role = next(d for d in docs if d["kind"] == "ClusterRole")
    for rule in role["rules"]:
        assert "*" not in rule["verbs"] and "*" not in rule["resources"], rule
        assert "secrets" not in rule["resources"], rule
    assert any("workloads" in r["resources"] for r in role["rules"])
    plain = next(d for d in yaml.safe_load_all(helm_template()) if d and d["kind"] == "ClusterRole")
    assert not any("workloads" in r["resources"] for r in plain["rules"])


def test_the_operator_binary_reads_every_variable_the_chart_sets(sadesim_operator):
    """The chart's env names are the `sadesim-operator` flags' variables (POD_* come from
    the downward API and name the leader-election Lease's namespace and holder)."""
    out = subprocess.run([sadesim_operator, "--help"], capture_output=True, text=True, check=True).stdout
    help_text = " ".join(out.split())  # clap wraps long lines
    docs = [d for d in yaml.safe_load_all(helm_template()) if d]
    deployment = next(d for d in docs if d["kind"] == "Deployment")
    env = {e["name"] for e in deployment["spec"]["template"]["spec"]["containers"][0]["env"]}
    flags = {name for name in env if name.startswith("SADESIM_")}
    assert flags == env - {"POD_NAMESPACE", "POD_NAME"}
    for name in sorted(flags):
        assert f"env: {name}" in help_text, f"{name} is not a sadesim-operator flag:\n{help_text}"


def test_a_run_with_onboard_cameras_and_gpus_passes_kubernetes_validate_strict(sadesim, venv_bin, tmp_path):
    """The renderer Deployment and Service, and the coordinator that renders the onboard
    cameras (the camera image, a GPU request, the frames' port) and the pilot that reads
    them, against Kubernetes' schemas."""
    doc = yaml.safe_load((REPO / "examples" / "precision-landing.yaml").read_text())
    doc["spec"]["rendering"] = {"enabled": True, "gpus": 1}
    doc["spec"]["pilot"]["image"] = "registry.example/team-a/landing:1"
    # Ground stations from two ranges: the NetworkPolicy's ipBlock rule is validated too.
    doc["spec"]["groundStations"] = {"allowFrom": ["10.20.0.0/16", "fd00::/8"]}
    scenario = tmp_path / "cameras.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    text = manifests(sadesim, str(scenario))
    assert {"Deployment/precision-landing-renderer", "Service/precision-landing-renderer"} <= set(kinds(text)), kinds(text)
    result = kubernetes_validate(venv_bin, text)
    assert result.returncode == 0, result.stdout + result.stderr
    docs = [d for d in yaml.safe_load_all(text) if d]
    pods = {
        d["metadata"]["name"]: (d["spec"] if d["kind"] == "Pod" else d["spec"]["template"]["spec"])
        for d in docs
        if d["kind"] in ("Pod", "Job", "Deployment")
    }
    limits = {name: spec["containers"][0]["resources"].get("limits", {}) for name, spec in pods.items()}
    assert {name for name, lim in limits.items() if "nvidia.com/gpu" in lim} == {"precision-landing-coordinator"}
    coordinator = pods["precision-landing-coordinator"]["containers"][0]
    assert coordinator["image"].startswith("ghcr.io/sadesim/sim-worker-camera:")
    assert pods["precision-landing-renderer"]["containers"][0]["image"].startswith("ghcr.io/sadesim/sim-worker:")
    pilot_env = {e["name"]: e.get("value") for e in pods["precision-landing-pilot"]["containers"][0]["env"]}
    url = pilot_env["SADESIM_CAMERAS_URL"]
    assert url == "http://precision-landing-airspace.default.svc:8490/cameras", url
    fleet_cm = next(d for d in docs if d["kind"] == "ConfigMap" and d["metadata"]["name"] == "precision-landing-fleet")
    fleet = json.loads(fleet_cm["data"]["fleet.json"])
    assert all(d["cameras"]["down"] == f"{url}/{d['name']}/down/" for d in fleet["drones"]), fleet["drones"]
    renderer = next(d for d in docs if d["kind"] == "Deployment")
    assert renderer["metadata"]["ownerReferences"][0]["kind"] == "SimulationRun"
    policy = next(d for d in docs if d["kind"] == "NetworkPolicy")
    assert [p["ipBlock"]["cidr"] for p in policy["spec"]["ingress"][1]["from"]] == ["10.20.0.0/16", "fd00::/8"]


def test_every_dockerfile_passes_hadolint(venv_bin):
    """The Dockerfiles (not built on this machine, which has no Docker engine; the test
    cluster packs the same layout from the host's build) against hadolint's rules; an
    ignored rule is ignored in the Dockerfile itself, with its reason."""
    dockerfiles = sorted((REPO / "images").glob("*.Dockerfile"))
    assert len(dockerfiles) >= 4, dockerfiles
    result = subprocess.run([str(venv_bin / "hadolint"), *map(str, dockerfiles)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


E2E_RUNS = sorted(
    p.name
    for p in (REPO / "tests" / "e2e").glob("*.yaml")
    if next(yaml.safe_load_all(p.read_text()))["kind"] == "SimulationRun"
)


@pytest.mark.parametrize("scenario", E2E_RUNS)
def test_the_end_to_end_scenarios_make_valid_manifests(sadesim, venv_bin, scenario):
    """What tests/e2e/run.sh and teams.sh apply makes objects Kubernetes accepts, also as an
    operator with Kueue on, which teams.sh installs (the test cluster of tests/cluster/ runs
    both for real; this checks them against the schemas without one)."""
    text = manifests(sadesim, "--kueue", f"tests/e2e/{scenario}")
    result = kubernetes_validate(venv_bin, text)
    assert result.returncode == 0, result.stdout + result.stderr


def pod_count(doc):
    """How many pods a child object makes."""
    spec = doc.get("spec", {})
    if doc["kind"] == "Pod":
        return 1
    if doc["kind"] == "Job":
        return spec.get("parallelism", spec.get("completions", 1))
    if doc["kind"] == "Deployment":
        return spec.get("replicas", 1)
    return 0


@pytest.mark.parametrize("scenario", ["team-a.yaml", "team-b.yaml"])
def test_a_queued_run_is_one_kueue_workload_counting_every_pod(sadesim, venv_bin, scenario, tmp_path):
    """teams.sh's runs as Kueue sees them: the Workload comes first, its podSets follow
    Kueue's rules (1 to 8, DNS-label names, counts of at least 1), each role's podSet holds
    exactly that role's pods with their template (validated as a Pod), and no other object
    is queued by itself. kubernetes-validate has no schema for Kueue's kinds, so the
    Workload is checked here."""
    # With an archive (as on the cluster), so the assets Job is in the gang too.
    run = yaml.safe_load((REPO / "tests" / "e2e" / scenario).read_text())
    run["spec"]["archive"] = {"url": "s3://sadesim-runs"}
    path = tmp_path / scenario
    path.write_text(yaml.safe_dump(run))
    docs = [d for d in yaml.safe_load_all(manifests(sadesim, "--kueue", str(path))) if d]
    workload, children = docs[0], docs[1:]
    assert (workload["apiVersion"], workload["kind"]) == ("kueue.x-k8s.io/v1beta2", "Workload")
    assert workload["spec"]["queueName"] == run["spec"]["queue"]
    assert workload["metadata"]["labels"]["kueue.x-k8s.io/queue-name"] == run["spec"]["queue"]
    assert workload["metadata"]["ownerReferences"][0]["kind"] == "SimulationRun"
    sets = workload["spec"]["podSets"]
    assert 1 <= len(sets) <= 8
    pods = {}
    for d in children:
        assert "kueue.x-k8s.io/queue-name" not in d["metadata"].get("labels", {}), d["metadata"]["name"]
        role = d["metadata"]["labels"]["sadesim.io/role"]
        pods[role] = pods.get(role, 0) + pod_count(d)
    pods = {role: n for role, n in pods.items() if n}
    assert {s["name"]: s["count"] for s in sets} == pods
    assert "assets" in pods
    for s in sets:
        assert re.fullmatch(r"[a-z0-9]([-a-z0-9]*[a-z0-9])?", s["name"]) and s["count"] >= 1, s
        pod = {"apiVersion": "v1", "kind": "Pod", "metadata": {"name": s["name"], **s["template"].get("metadata", {})},
               "spec": s["template"]["spec"]}
        result = kubernetes_validate(venv_bin, yaml.safe_dump(pod))
        assert result.returncode == 0, (s["name"], result.stdout + result.stderr)


def test_the_shell_scripts_pass_shellcheck(venv_bin):
    """The end-to-end script, which cannot run on this machine, and CI's scripts."""
    scripts = [REPO / ".ci" / "run", *sorted((REPO / "tests").rglob("*.sh"))]
    assert REPO / "tests" / "e2e" / "run.sh" in scripts
    result = subprocess.run([str(venv_bin / "shellcheck"), *map(str, scripts)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


PILOTED = [name for name in EXAMPLES if "pilot" in yaml.safe_load((REPO / "examples" / name).read_text())["spec"]]


@pytest.mark.parametrize("example", PILOTED)
def test_every_piloted_example_runs_its_pilot_from_an_image_we_build(sadesim, example):
    """`kubectl apply` of a piloted example starts its pilot: the Job runs the image the
    example names, which one of images/*.Dockerfile builds, with a command that exists there."""
    assert len(PILOTED) >= 5, PILOTED
    spec = yaml.safe_load((REPO / "examples" / example).read_text())["spec"]
    image = spec["pilot"]["image"]
    repository, tag = image.rsplit(":", 1)
    assert repository.startswith("ghcr.io/sadesim/") and tag, image
    dockerfile = REPO / "images" / (repository.removeprefix("ghcr.io/sadesim/") + ".Dockerfile")
    assert dockerfile.exists(), f"{example}: no {dockerfile.relative_to(REPO)} builds {image}"
    docs = [d for d in yaml.safe_load_all(manifests(sadesim, f"examples/{example}")) if d]
    job = next(d for d in docs if d["kind"] == "Job" and d["metadata"]["name"].endswith("-pilot"))
    container = job["spec"]["template"]["spec"]["containers"][0]
    assert container["image"] == image
    env = {e["name"]: e.get("value") for e in container["env"]}
    assert env["SADESIM_FLEET"] == "/etc/sadesim/fleet.json" and env["SADESIM_SCENARIO"] == "/etc/sadesim/scenario.json"
    text = dockerfile.read_text()
    command = container.get("command")
    if command and command[0] == "python3":
        # The Python examples run from /pilot with the scripts under /pilot/pilots.
        script = command[1]
        assert script.startswith("pilots/") and (REPO / "examples" / script).exists(), command
        assert "COPY examples/pilots/*.py /pilot/pilots/" in text, dockerfile
        assert "WORKDIR /pilot" in (REPO / "images" / "pilot-python.Dockerfile").read_text()
    else:
        # The Rust pilot: its entrypoint, or the binary the scenario names.
        binary = command[0] if command else None
        entrypoint = json.loads(text.split("ENTRYPOINT", 1)[1].strip().splitlines()[0])[0]
        assert binary in (None, entrypoint), (binary, entrypoint)
        assert "cargo build --release --locked -p chicago-pilot" in text


def test_the_pilot_images_pin_the_versions_the_tests_fly_with():
    """The base and example pilot images install exactly the MAVSDK, pymavlink and OpenCV the
    interop tests use, so a pilot that passes here behaves the same in its image."""
    def pins(path):
        lines = [l.split("#")[0].strip() for l in path.read_text().splitlines()]
        return dict(l.split("==") for l in lines if l)
    tested = pins(REPO / "tests" / "requirements.txt")
    for name in ["pilot-python.requirements.txt", "pilot-examples.requirements.txt"]:
        image = pins(REPO / "images" / name)
        assert image, name
        for package, version in image.items():
            if package in tested:
                assert tested[package] == version, (name, package, version, tested[package])
    assert {"mavsdk", "pymavlink"} <= set(pins(REPO / "images" / "pilot-python.requirements.txt"))


def test_the_example_pilots_requirements_pin_what_they_import_as_the_tests_do():
    """`pip install -r examples/pilots/requirements.txt` (the README's one command) gets every
    package the example pilots import, at the versions the interop tests fly with and the
    pilots' image has."""
    def pins(path):
        lines = [l.split("#")[0].strip() for l in path.read_text().splitlines()]
        return dict(l.split("==") for l in lines if l)
    needed = pins(REPO / "examples" / "pilots" / "requirements.txt")
    # numpy comes into the tests' environment with OpenCV; the pilots' image pins it.
    tested = pins(REPO / "images" / "pilot-examples.requirements.txt") | pins(REPO / "tests" / "requirements.txt")
    assert {p: tested.get(p) for p in needed} == needed, (needed, tested)
    package_of = {"cv2": "opencv-python-headless", "numpy": "numpy", "pymavlink": "pymavlink", "mavsdk": "mavsdk"}
    for script in sorted((REPO / "examples" / "pilots").glob("*.py")):
        tree = ast.parse(script.read_text())
        modules = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        modules |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
        third_party = modules - set(sys.stdlib_module_names)
        assert third_party <= set(package_of), (script.name, third_party)
        assert {package_of[m] for m in third_party} <= set(needed), (script.name, third_party, needed)


def test_the_chart_lets_the_operator_apply_and_delete_every_kind_of_child(sadesim):
    """Every kind `sadesim manifests` prints for the examples (the children the operator
    server-side applies and deletes by label) is in the chart's ClusterRole with those verbs."""
    docs = [d for d in yaml.safe_load_all(helm_template()) if d]
    rules = next(d for d in docs if d["kind"] == "ClusterRole")["rules"]
    plural = {"NetworkPolicy": "networkpolicies"}
    needed = set()
    for example in EXAMPLES:
        for d in yaml.safe_load_all(manifests(sadesim, f"examples/{example}")):
            if d:
                group = d["apiVersion"].rsplit("/", 1)[0] if "/" in d["apiVersion"] else ""
                needed.add((group, plural.get(d["kind"], d["kind"].lower() + "s")))
    assert ("networking.k8s.io", "networkpolicies") in needed and ("apps", "deployments") in needed, needed

    def check(rules, needed):
        for group, resource in sorted(needed):
            verbs = set()
            for rule in rules:
                if group in rule["apiGroups"] and resource in rule["resources"]:
                    verbs |= set(rule["verbs"])
            assert {"get", "list", "create", "patch", "deletecollection"} <= verbs, (group, resource, verbs)

    check(rules, needed)
    # With Kueue on: the run's Workload too, the flavors it is admitted to, and the queue
    # position (Kueue's visibility API).
    kueue_docs = [d for d in yaml.safe_load_all(helm_template("--set", "kueue.enabled=true")) if d]
    kueue_rules = next(d for d in kueue_docs if d["kind"] == "ClusterRole")["rules"]
    queued = [d for d in yaml.safe_load_all(manifests(sadesim, "--kueue", "tests/e2e/team-a.yaml")) if d]
    assert queued[0]["kind"] == "Workload"
    check(kueue_rules, {("kueue.x-k8s.io", "workloads")})
    granted = {(g, r, v) for rule in kueue_rules for g in rule["apiGroups"] for r in rule["resources"] for v in rule["verbs"]}
    assert ("kueue.x-k8s.io", "resourceflavors", "get") in granted
    assert ("visibility.kueue.x-k8s.io", "localqueues/pendingworkloads", "get") in granted
