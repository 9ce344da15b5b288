"""The SimulationRun CRD against Kubernetes' own schemas (kubernetes-validate) and the
example scenarios against the CRD's OpenAPI schema (what the API server checks on apply)."""
import copy
import subprocess

import pytest
import yaml
from openapi_schema_validator import OAS30Validator


def crd_text(sadesim) -> str:
    return subprocess.run([sadesim, "crd"], check=True, capture_output=True, text=True).stdout


def kubernetes_validate(venv_bin, text):
    return subprocess.run(
        [str(venv_bin / "kubernetes-validate"), "--strict", "-"], input=text, capture_output=True, text=True
    )


def test_crd_passes_kubernetes_validate_strict(sadesim, venv_bin):
    result = kubernetes_validate(venv_bin, crd_text(sadesim))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "passed" in result.stdout


def test_kubernetes_validate_rejects_a_broken_crd(sadesim, venv_bin):
    # Guards the check above: the tool does fail on a CRD with an unknown field.
    crd = yaml.safe_load(crd_text(sadesim))
    crd["spec"]["versions"][0]["colour"] = "red"
    result = kubernetes_validate(venv_bin, yaml.safe_dump(crd))
    assert result.returncode != 0


@pytest.fixture(scope="module")
def validator(sadesim):
    crd = yaml.safe_load(crd_text(sadesim))
    schema = crd["spec"]["versions"][0]["schema"]["openAPIV3Schema"]
    return OAS30Validator(schema)


def scenario_docs(repo):
    paths = sorted(repo.glob("examples/*.yaml")) + sorted(repo.glob("tests/scenarios/valid/*.yaml"))
    for path in paths:
        for doc in yaml.safe_load_all(path.read_text()):
            if doc is None:
                continue
            items = doc["items"] if doc.get("kind") == "List" else [doc]
            for item in items:
                yield path.name, item


def test_examples_conform_to_the_crd_schema(repo, validator):
    docs = list(scenario_docs(repo))
    assert len(docs) >= 3
    for name, doc in docs:
        errors = [f"{'.'.join(map(str, e.path))}: {e.message}" for e in validator.iter_errors(doc)]
        assert errors == [], f"{name}: {errors}"


def test_schema_rejects_out_of_range_and_unknown_enum(repo, validator):
    doc = next(d for n, d in scenario_docs(repo) if n == "quickstart.yaml")
    bad = copy.deepcopy(doc)
    bad["spec"]["fleet"][0]["count"] = 0
    assert any("count" in map(str, e.path) for e in validator.iter_errors(bad))
    bad = copy.deepcopy(doc)
    bad["spec"]["clock"] = {"mode": "warp"}
    assert list(validator.iter_errors(bad))
    bad = copy.deepcopy(doc)
    bad["spec"]["origin"]["latitudeDeg"] = 91
    assert list(validator.iter_errors(bad))
