"""The images on the real cluster: every image the examples and the installed chart name is on
the node (tests/cluster/images.sh built it here), and the two images that are more than the
worker's binaries work in the pods that use them: the OpenFOAM worker image computes a run's
urban wind field in its assets Job, and the Chicago case study's pilot image flies its run."""
import json
import pathlib
import re

import pytest
import yaml

from kube import wait_for, wait_phase

REPO = pathlib.Path(__file__).resolve().parents[2]
# Where the cluster's object store keeps its buckets (tests/cluster/objectstore.sh: Versity's
# posix backend, one folder per bucket).
OBJECT_STORE_DIR = pathlib.Path("/var/lib/sadesim-cluster/objectstore")


def example_images() -> dict:
    """{image: example file} for every `spec.pilot.image` in examples/."""
    images = {}
    for path in sorted((REPO / "examples").glob("*.yaml")):
        for doc in yaml.safe_load_all(path.read_text()):
            image = ((doc or {}).get("spec") or {}).get("pilot", {}).get("image")
            if image:
                images[image] = path.name
    return images


def operator_images(kubectl, namespace) -> dict:
    """{image: where} for the installed chart's operator: its own image and the images it gives
    its runs' pods (SADESIM_*_IMAGE)."""
    deployment = kubectl.json("deployment", "sadesim", "-n", namespace)
    container = deployment["spec"]["template"]["spec"]["containers"][0]
    images = {container["image"]: "the operator Deployment"}
    for env in container.get("env", []):
        if env["name"].endswith("_IMAGE"):
            images[env["value"]] = f"the operator's {env['name']}"
    return images


def node_images(kubectl) -> set:
    """Every name of every image the kubelet reports on the node (status.images)."""
    node = kubectl.json("nodes")["items"][0]
    return {name for image in node["status"].get("images", []) for name in image["names"]}


def test_every_image_the_examples_and_the_chart_name_is_on_the_node(kubectl, operator):
    named = {**example_images(), **operator_images(kubectl, operator)}
    # The chart names at least the operator, worker, camera and OpenFOAM images, the examples
    # the Python and the Chicago pilots.
    assert len(named) >= 6, named
    # The kubelet reports the node's images every few seconds: the lane imported them just now.
    def missing():
        on_node = node_images(kubectl)
        gone = {image: where for image, where in named.items() if image not in on_node}
        return None if gone else on_node

    wait_for("every named image in the node's status.images", 90, missing, every=3)


def openfoam_run() -> dict:
    """One drone hovering for 30 s over a 200 m square of procedural city in a west wind whose
    flow around the buildings OpenFOAM computes (10 m cells: a few seconds of simpleFoam)."""
    return {
        "apiVersion": "sadesim.io/v1alpha1", "kind": "SimulationRun", "metadata": {"name": "openfoam-wind"},
        "spec": {
            "origin": {"latitudeDeg": 41.8796, "longitudeDeg": -87.6237, "altitudeMslM": 181},
            "duration": "30s", "clock": {"mode": "asFastAsPossible"}, "seed": 1,
            "world": {"extentM": 100},
            "environment": {"wind": {"speedMps": 6, "directionFromDeg": 270,
                                     "urban": {"model": "openfoam", "spacingM": 10}}},
            "fleet": [{
                "name": "probe", "count": 1, "airframe": "x500", "operator": "tests",
                "homes": {"explicit": [{"latitudeDeg": 41.8796, "longitudeDeg": -87.6237}]},
                "altitude": {"maxAglM": 80},
                "mission": {"items": [{"takeoff": {"altitudeAglM": 40}}, {"loiter": {"holdS": 600}}]},
            }],
        },
    }


def test_the_openfoam_image_computes_a_runs_urban_wind_in_its_assets_job(kubectl, operator, namespace):
    """The assets Job of a `model: openfoam` run (in the OpenFOAM image: the worker image has
    no OpenFOAM, and the Job would fail saying so) runs blockMesh, snappyHexMesh and
    simpleFoam and stores the field in the archive's asset cache, where the run's shards load
    it; the run flies and succeeds."""
    run = openfoam_run()
    name = run["metadata"]["name"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=json.dumps(run))
    done = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"}, seconds=420)
    assert done["status"]["phase"] == "Succeeded", done["status"]
    assert done["status"]["simTimeS"] == pytest.approx(30, abs=0.5)

    # The pods are gone once the run has ended; their logs are in its archive (read from the
    # object store's own folder).
    archive = done["status"]["archive"]["url"]
    assert archive.startswith("s3://"), archive
    folder = OBJECT_STORE_DIR / archive.removeprefix("s3://")
    logs = sorted((folder / "logs").glob(f"{name}-assets-*.log"))
    assert logs, sorted(p.name for p in (folder / "logs").iterdir())
    log = logs[0].read_text()
    stored = re.search(r"urban wind field computed and stored: s3://(\S+)", log)
    assert stored, log

    # The stored field: OpenFOAM's, for the sector of the run's wind (from 270°).
    attrs = json.loads((OBJECT_STORE_DIR / stored.group(1) / "wind.zarr" / ".zattrs").read_text())
    assert attrs["model"] == "openfoam", attrs
    assert [s["directionFromDeg"] for s in attrs["sectors"]] == [270.0], attrs["sectors"]


def test_the_chicago_case_study_flies_with_its_pilot_image(kubectl, operator, namespace):
    """examples/chicago-museum.yaml as a user applies it, on a clock as fast as the machine
    goes (the pilot times everything on the drones' clock): the pilot Job from the Chicago
    pilot image flies the 32 drones through the run's shards and airspace API, ends the run
    when they have landed, and the case study's criteria pass. (Its pilot resolves the shards'
    DNS names with retries: released well under a second after the shards started, it once
    asked before cluster DNS served shard-0's name, and half the fleet never flew.)"""
    run = next(d for d in yaml.safe_load_all((REPO / "examples/chicago-museum.yaml").read_text()) if d)
    run["spec"]["clock"] = {"mode": "asFastAsPossible"}
    name = run["metadata"]["name"]
    kubectl.run("apply", "-n", namespace, "-f", "-", input=json.dumps(run))
    # The pilot Job runs the pilot image (the operator deletes the Job once the run ends).
    pilot = wait_for(f"{name}'s pilot pod", 300, lambda: next(iter(
        kubectl.json("pods", "-n", namespace, "-l", f"sadesim.io/run={name},sadesim.io/role=pilot")["items"]), None),
        every=1)
    assert pilot["spec"]["containers"][0]["image"] == run["spec"]["pilot"]["image"]
    done = wait_phase(kubectl, namespace, name, {"Succeeded", "Failed", "Aborted"}, seconds=600)
    assert done["status"]["phase"] == "Succeeded", done["status"]
    running = next(c for c in done["status"]["conditions"] if c["type"] == "Running")
    assert "(pilotExited)" in running["message"], running
    assert done["status"]["verdict"]["passed"] is True, done["status"]["verdict"]
    # The example archives to file://runs for local runs: on a cluster that is a folder inside
    # the pods, so nothing is archived and the run says so (it does not retry forever).
    archived = next(c for c in done["status"]["conditions"] if c["type"] == "Archived")
    assert (archived["status"], archived["reason"]) == ("False", "NoArchive"), archived
    assert '"file://runs" is not an object store' in archived["message"], archived
