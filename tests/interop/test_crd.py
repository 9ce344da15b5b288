"""The CRDs (`sadesim crd`: SimulationRun, then SimulationSweep) against Kubernetes' own
schemas (kubernetes-validate), and the example scenarios and sweeps against their CRD's
OpenAPI schema (what the API server checks on apply)."""
import copy
import subprocess

import pytest
import yaml
from openapi_schema_validator import OAS30Validator


def crd_text(sadesim) -> str:
    return subprocess.run([sadesim, "crd"], check=True, capture_output=True, text=True).stdout


def crds(sadesim) -> dict:
    """{kind: CRD} of every CRD `sadesim crd` prints."""
    return {c["spec"]["names"]["kind"]: c for c in yaml.safe_load_all(crd_text(sadesim)) if c}


def test_crd_prints_both_crds(sadesim):
    assert sorted(crds(sadesim)) == ["SimulationRun", "SimulationSweep"]


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
    crd = crds(sadesim)["SimulationSweep"]
    crd["spec"]["versions"][0]["colour"] = "red"
    result = kubernetes_validate(venv_bin, yaml.safe_dump(crd))
    assert result.returncode != 0


@pytest.fixture(scope="module")
def validator(sadesim):
    schema = crds(sadesim)["SimulationRun"]["spec"]["versions"][0]["schema"]["openAPIV3Schema"]
    return OAS30Validator(schema)


def test_example_sweeps_conform_to_the_sweep_crd_schema(repo, sadesim):
    schema = crds(sadesim)["SimulationSweep"]["spec"]["versions"][0]["schema"]["openAPIV3Schema"]
    validator = OAS30Validator(schema)
    paths = sorted(repo.glob("examples/sweeps/*.yaml")) + sorted(repo.glob("tests/engine/sweeps/*.yaml"))
    assert len(paths) >= 4
    for path in paths:
        doc = yaml.safe_load(path.read_text())
        errors = [f"{'.'.join(map(str, e.path))}: {e.message}" for e in validator.iter_errors(doc)]
        assert errors == [], f"{path.name}: {errors}"
    broken = yaml.safe_load(paths[0].read_text())
    broken["spec"]["parameters"][0]["range"] = {"from": "zero"}
    assert list(validator.iter_errors(broken)), "the schema refuses a range of strings"


def scenario_docs(repo):
    paths = sorted(repo.glob("examples/*.yaml")) + sorted(repo.glob("examples/maps/*.yaml"))
    paths += sorted(repo.glob("tests/scenarios/valid/*.yaml"))
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


def transition_rules(sadesim):
    """Every CEL rule of spec and its direct fields that compares with `oldSelf`, as
    (field or None for spec itself, rule), evaluated the way the API server does on update:
    a field's rule only when the field exists in both old and new objects."""
    crd = crds(sadesim)["SimulationRun"]
    spec = crd["spec"]["versions"][0]["schema"]["openAPIV3Schema"]["properties"]["spec"]
    rules = [(None, r["rule"]) for r in spec.get("x-kubernetes-validations", []) if "oldSelf" in r["rule"]]
    for name, prop in spec["properties"].items():
        rules += [(name, r["rule"]) for r in prop.get("x-kubernetes-validations", []) if "oldSelf" in r["rule"]]
    return rules


def update_allowed(rules, old, new):
    """Whether the API server's transition rules accept changing spec `old` into `new`;
    returns the fields (None: spec) whose rule refused."""
    import celpy

    env = celpy.Environment()
    refused = []
    for field, rule in rules:
        if field is None:
            values = {"self": new, "oldSelf": old}
        elif field in new and field in old:
            values = {"self": new[field], "oldSelf": old[field]}
        else:
            continue
        program = env.program(env.compile(rule))
        if not program.evaluate({k: celpy.json_to_cel(v) for k, v in values.items()}):
            refused.append(field)
    return refused


def test_spec_is_immutable_after_creation_except_abort(sadesim, repo):
    """The CRD's CEL transition rules, evaluated with cel-python: every spec field but
    `abort` is refused a change, and optional fields cannot be added or removed."""
    rules = transition_rules(sadesim)
    fields = {f for f, _ in rules if f}
    spec_props = set(crds(sadesim)["SimulationRun"]["spec"]["versions"][0]["schema"]["openAPIV3Schema"]["properties"]["spec"]["properties"])
    assert fields == spec_props - {"abort"}, "every field but abort has a transition rule"
    old = yaml.safe_load((repo / "examples" / "chicago-museum.yaml").read_text())["spec"]
    assert update_allowed(rules, old, copy.deepcopy(old)) == []
    aborted = copy.deepcopy(old)
    aborted["abort"] = True
    assert update_allowed(rules, old, aborted) == []

    longer = copy.deepcopy(old)
    longer["duration"] = "20m"
    assert update_allowed(rules, old, longer) == ["duration"]
    more = copy.deepcopy(old)
    more["fleet"][0]["count"] += 1
    assert update_allowed(rules, old, more) == ["fleet"]
    seeded = copy.deepcopy(old)
    seeded.pop("seed", None) if "seed" in old else seeded.update(seed=7)
    assert update_allowed(rules, old, seeded) == [None], "adding or removing a field is refused"
    both = copy.deepcopy(aborted)
    both["duration"] = "1m"
    assert update_allowed(rules, old, both) == ["duration"], "abort does not carry other changes through"


def all_rules(sadesim):
    """Every CEL rule of the CRD that does not compare with `oldSelf`, as (path, rule):
    `.spec.fleet[]` is the rule of each item of `spec.fleet`."""
    crd = crds(sadesim)["SimulationRun"]
    found = []

    def walk(schema, path):
        found.extend((path, r["rule"]) for r in schema.get("x-kubernetes-validations", []) if "oldSelf" not in r["rule"])
        for name, prop in schema.get("properties", {}).items():
            walk(prop, f"{path}.{name}")
        if "items" in schema:
            walk(schema["items"], f"{path}[]")

    walk(crd["spec"]["versions"][0]["schema"]["openAPIV3Schema"], "")
    return found


EXPLICIT = [{"latitudeDeg": 41.88, "longitudeDeg": -87.62}]
ZONE = {"reference": "agl", "heightM": 120}
# For each rule (path, then a word of the rule to tell rules at one path apart): objects the
# rule accepts (True) and refuses (False), as `self` at that path.
CEL_CASES = {
    (".spec", "pilot"): [
        ({"fleet": [{"mission": {}}]}, True),
        ({"pilot": {"command": ["p"]}, "fleet": [{}]}, True),
        ({"fleet": [{"mission": {}}, {}]}, False),
    ],
    (".spec.clock", "scaled"): [
        ({"mode": "scaled", "factor": 4}, True),
        ({"mode": "realtime"}, True),
        ({"mode": "scaled"}, False),
        ({"mode": "asFastAsPossible", "factor": 2}, False),
    ],
    (".spec.fleet[]", "explicit"): [
        ({"count": 1, "homes": {"explicit": EXPLICIT}}, True),
        ({"count": 3, "homes": {"randomInArea": {}}}, True),
        ({"count": 2, "homes": {"explicit": EXPLICIT}}, False),
    ],
    (".spec.fleet[].altitude", "minAglM"): [
        ({"maxAglM": 120}, True),
        ({"minAglM": 30, "maxAglM": 120}, True),
        ({"minAglM": 120, "maxAglM": 120}, False),
    ],
    (".spec.world", "== has(self.osm)"): [
        ({"source": "osm", "osm": {"file": "a.pbf"}}, True),
        ({"source": "procedural"}, True),
        ({}, True),
        ({"source": "osm"}, False),
        ({"osm": {"file": "a.pbf"}}, False),
    ],
    (".spec.world", "openAreas"): [
        ({"source": "osm", "osm": {"file": "a.pbf"}}, True),
        ({"city": {}, "openAreas": []}, True),
        ({"source": "osm", "osm": {"file": "a.pbf"}, "city": {}}, False),
        ({"source": "osm", "osm": {"file": "a.pbf"}, "openAreas": []}, False),
    ],
    (".spec.zones[]", "floor"): [
        ({"ceiling": ZONE}, True),
        ({"floor": {"reference": "agl", "heightM": 30}, "ceiling": ZONE}, True),
        ({"floor": {"reference": "msl", "heightM": 300}, "ceiling": ZONE}, True),
        ({"floor": {"reference": "agl", "heightM": 120}, "ceiling": ZONE}, False),
    ],
    (".spec.zones[].policy", "minAltitudeAglM"): [
        ({}, True),
        ({"minAltitudeAglM": 100, "maxAltitudeAglM": 120}, True),
        ({"minAltitudeAglM": 130, "maxAltitudeAglM": 120}, False),
    ],
}


def test_every_cel_rule_accepts_and_refuses_what_it_should(sadesim):
    """Every `x-kubernetes-validations` rule of the CRD (the transition rules are tested
    above) evaluated with cel-python, an independent CEL implementation, on at least one
    object it must accept and one it must refuse; a new rule without cases fails here."""
    import celpy

    env = celpy.Environment()
    rules = all_rules(sadesim)
    assert len(rules) >= 8, rules
    covered = set()
    for path, rule in rules:
        keys = [k for k in CEL_CASES if k[0] == path and k[1] in rule]
        assert len(keys) == 1, f"no case (or several) for the rule at {path}: {rule}"
        covered.add(keys[0])
        cases = CEL_CASES[keys[0]]
        assert {True, False} <= {expected for _, expected in cases}, keys[0]
        program = env.program(env.compile(rule))
        for value, expected in cases:
            got = bool(program.evaluate({"self": celpy.json_to_cel(value)}))
            assert got == expected, f"{path}: {rule}\n  on {value}: {got}, expected {expected}"
    assert covered == set(CEL_CASES), set(CEL_CASES) - covered
