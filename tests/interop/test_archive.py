"""Run archives in object storage, end to end: `sadesim archive put/ls/verify/get` and
`sadesim run` with an `s3://` archive, against a real S3-compatible server (moto's
standalone server, started here on 127.0.0.1:MOTO_PORT) and checked with boto3.

The port is fixed: do not run these tests in parallel with each other (no `pytest -n`).
"""
import hashlib
import json
import os
import pathlib
import signal
import subprocess
import time
import urllib.request

import boto3
import pytest
import yaml
from test_assets import mission
from test_osm import helsinki  # noqa: F401  (the fixture)

MOTO_PORT = 9521  # not used by the port plan (MAVLink 14540+/24600+, 5760, 14550, 7400, 8480, 8490, 9090)
ENDPOINT = f"http://127.0.0.1:{MOTO_PORT}"
BUCKET = "sadesim-evidence"
PREFIX = "teams/blue"
ARCHIVE = f"s3://{BUCKET}/{PREFIX}"
# moto accepts any credentials; the region is needed by the signer.
AWS_ENV = {
    "AWS_ACCESS_KEY_ID": "testing",
    "AWS_SECRET_ACCESS_KEY": "testing",
    "AWS_REGION": "us-east-1",
    "AWS_ENDPOINT_URL": ENDPOINT,
    "AWS_ALLOW_HTTP": "true",
}
# Larger than the multipart threshold (8 MiB): goes up in parts.
BIG_BYTES = 9 * 1024 * 1024 + 4321


def wait_for_server(timeout_s: float = 30.0):
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with urllib.request.urlopen(f"{ENDPOINT}/moto-api/", timeout=1):
                return
        except OSError:
            if time.monotonic() > deadline:
                raise AssertionError(f"moto_server did not answer on {ENDPOINT} within {timeout_s} s")
            time.sleep(0.2)


@pytest.fixture(scope="module")
def s3(venv_bin, tmp_path_factory):
    """A boto3 S3 client on a fresh moto server with the bucket `BUCKET`."""
    log = open(tmp_path_factory.mktemp("moto") / "moto.log", "w")
    server = subprocess.Popen(
        [str(venv_bin / "moto_server"), "-H", "127.0.0.1", "-p", str(MOTO_PORT)],
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    try:
        wait_for_server()
        client = boto3.client(
            "s3",
            endpoint_url=ENDPOINT,
            region_name=AWS_ENV["AWS_REGION"],
            aws_access_key_id=AWS_ENV["AWS_ACCESS_KEY_ID"],
            aws_secret_access_key=AWS_ENV["AWS_SECRET_ACCESS_KEY"],
        )
        client.create_bucket(Bucket=BUCKET)
        yield client
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=10)
        log.close()


def sadesim_cmd(sadesim, *args, cwd=None):
    env = {**os.environ, **AWS_ENV}
    return subprocess.run([sadesim, *args], capture_output=True, text=True, env=env, cwd=cwd, timeout=300)


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def make_run(folder: pathlib.Path) -> dict[str, bytes]:
    """A run folder as `sadesim run` leaves it, with a sub-folder and one large file."""
    files = {
        "events.jsonl": b'{"timeS":0.0,"event":"runStarted","drones":1,"shards":1}\n',
        "summary.json": b'{"run":"quickstart"}\n',
        "ulog/drone-0.ulg": bytes(range(256)) * 40,
        "trajectory.csv": os.urandom(BIG_BYTES),
    }
    for rel, data in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return files


def objects(s3, prefix: str) -> dict[str, bytes]:
    listed = s3.list_objects_v2(Bucket=BUCKET, Prefix=prefix + "/").get("Contents", [])
    return {o["Key"][len(prefix) + 1 :]: s3.get_object(Bucket=BUCKET, Key=o["Key"])["Body"].read() for o in listed}


def put(sadesim, folder, uid):
    out = sadesim_cmd(sadesim, "archive", "put", str(folder), ARCHIVE, "--run", "quickstart", "--uid", uid)
    assert out.returncode == 0, out.stdout + out.stderr
    return f"{ARCHIVE}/default/quickstart/{uid}"


def test_put_ls_verify_get_round_trip(sadesim, s3, tmp_path):
    files = make_run(tmp_path / "run")
    url = put(sadesim, tmp_path / "run", "uid-ok")

    # The layout and the manifest, read back with boto3.
    stored = objects(s3, f"{PREFIX}/default/quickstart/uid-ok")
    assert sorted(stored) == sorted([*files, "manifest.json"])
    for rel, data in files.items():
        assert stored[rel] == data, rel
    manifest = json.loads(stored["manifest.json"])
    assert manifest["formatVersion"] == 1
    assert (manifest["namespace"], manifest["run"], manifest["uid"]) == ("default", "quickstart", "uid-ok")
    assert manifest["files"] == [
        {"path": rel, "size": len(files[rel]), "sha256": sha256(files[rel])} for rel in sorted(files)
    ]
    assert manifest["totalBytes"] == sum(len(d) for d in files.values())

    ls = sadesim_cmd(sadesim, "archive", "ls", ARCHIVE)
    assert ls.returncode == 0, ls.stdout + ls.stderr
    line = next(l for l in ls.stdout.splitlines() if l.startswith("default/quickstart/uid-ok "))
    assert line.split()[1] == "4" and line.endswith("complete"), ls.stdout

    verify = sadesim_cmd(sadesim, "archive", "verify", url)
    assert verify.returncode == 0, verify.stdout + verify.stderr
    assert verify.stdout.startswith(f"ok: {url}: verified 4 files"), verify.stdout

    got = tmp_path / "got"
    get = sadesim_cmd(sadesim, "archive", "get", url, str(got))
    assert get.returncode == 0, get.stdout + get.stderr
    for rel, data in files.items():
        assert (got / rel).read_bytes() == data, rel
    assert json.loads((got / "manifest.json").read_bytes()) == manifest


def test_a_flipped_byte_fails_verify_naming_the_file(sadesim, s3, tmp_path):
    files = make_run(tmp_path / "run")
    url = put(sadesim, tmp_path / "run", "uid-flip")
    key = f"{PREFIX}/default/quickstart/uid-flip/ulog/drone-0.ulg"
    data = bytearray(s3.get_object(Bucket=BUCKET, Key=key)["Body"].read())
    data[100] ^= 0x40
    s3.put_object(Bucket=BUCKET, Key=key, Body=bytes(data))

    verify = sadesim_cmd(sadesim, "archive", "verify", url)
    assert verify.returncode == 1, verify.stdout + verify.stderr
    assert f"error: {url}: 1 problem" in verify.stdout
    expected = sha256(files["ulog/drone-0.ulg"])
    actual = sha256(bytes(data))
    assert f"ulog/drone-0.ulg: sha256 mismatch: expected {expected}, actual {actual}" in verify.stdout, verify.stdout

    # `get` downloads and checks too.
    get = sadesim_cmd(sadesim, "archive", "get", url, str(tmp_path / "got"))
    assert get.returncode == 1, get.stdout + get.stderr
    assert "ulog/drone-0.ulg: sha256 mismatch" in get.stdout


def test_a_run_without_manifest_is_incomplete(sadesim, s3, tmp_path):
    make_run(tmp_path / "run")
    url = put(sadesim, tmp_path / "run", "uid-partial")
    s3.delete_object(Bucket=BUCKET, Key=f"{PREFIX}/default/quickstart/uid-partial/manifest.json")

    ls = sadesim_cmd(sadesim, "archive", "ls", ARCHIVE)
    line = next(l for l in ls.stdout.splitlines() if l.startswith("default/quickstart/uid-partial "))
    assert line.endswith("incomplete (no manifest.json)"), ls.stdout
    verify = sadesim_cmd(sadesim, "archive", "verify", url)
    assert verify.returncode == 1
    assert "manifest.json: missing: the run is incomplete" in verify.stdout, verify.stdout


def test_a_failed_upload_is_reported_naming_the_file(sadesim, s3, tmp_path):
    make_run(tmp_path / "run")
    out = sadesim_cmd(sadesim, "archive", "put", str(tmp_path / "run"), "s3://no-such-bucket/x", "--run", "r", "--uid", "u")
    assert out.returncode == 2, out.stdout + out.stderr
    assert f"error: failed to upload {tmp_path / 'run'}/" in out.stderr, out.stderr
    assert "s3://no-such-bucket/x/default/r/u/" in out.stderr, out.stderr


def test_sadesim_run_uploads_to_an_s3_archive(sadesim, s3, repo, tmp_path):
    doc = yaml.safe_load((repo / "examples" / "quickstart.yaml").read_text())
    doc["spec"]["duration"] = "15s"
    doc["spec"]["archive"] = {"url": ARCHIVE}
    scenario = tmp_path / "quickstart.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    out = sadesim_cmd(sadesim, "run", str(scenario), "--quiet", "--no-mavlink", "--out", str(tmp_path / "runs"))
    assert out.returncode == 0, out.stdout + out.stderr
    local = pathlib.Path(next(l for l in out.stdout.splitlines() if "output:" in l).split("output: ")[1])
    uid = local.name
    url = f"{ARCHIVE}/default/quickstart/{uid}"
    assert f"  archived: {url}/" in out.stdout, out.stdout

    # The local folder keeps its own manifest, equal to the uploaded one.
    stored = objects(s3, f"{PREFIX}/default/quickstart/{uid}")
    assert json.loads(stored["manifest.json"]) == json.loads((local / "manifest.json").read_bytes())
    assert {"plan.json", "events.jsonl", "summary.json", "trajectory.csv"} <= set(stored)
    for where in (url, str(local)):
        verify = sadesim_cmd(sadesim, "archive", "verify", where)
        assert verify.returncode == 0, verify.stdout + verify.stderr


def test_a_world_in_object_storage_is_fetched_and_keyed_by_its_bytes(s3, sadesim, helsinki, tmp_path):  # noqa: F811
    """`world.osm.file: s3://...` (what a Kubernetes run names): `sadesim run` fetches the
    extract from the S3 server; the asset cache key is the same as for the same bytes on
    disk (content-addressed, not by location); a missing object is a one-line error naming
    the field and the URL. `sadesim manifests` plans it as the operator would."""
    extract = helsinki
    s3.put_object(Bucket=BUCKET, Key="maps/helsinki.osm.pbf", Body=extract.read_bytes())
    url = f"s3://{BUCKET}/maps/helsinki.osm.pbf"

    def plan_key(file: str) -> str:
        doc = mission(file)
        path = tmp_path / "world.json"
        path.write_text(json.dumps(doc))
        done = sadesim_cmd(sadesim, "plan", str(path), "--json")
        assert done.returncode == 0, done.stdout + done.stderr
        return json.loads(done.stdout)["assetCacheKey"]

    assert plan_key(url) == plan_key(str(extract))

    doc = mission(url)
    path = tmp_path / "remote.json"
    path.write_text(json.dumps(doc))
    cache = f"file://{tmp_path / 'cache'}"
    done = sadesim_cmd(sadesim, "run", str(path), "--out", str(tmp_path / "runs"), "-q", "--no-mavlink",
                       "--asset-cache", cache)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "criteria PASSED" in done.stdout and "assets built:" in done.stdout, done.stdout

    manifests = sadesim_cmd(sadesim, "manifests", str(path))
    assert manifests.returncode == 0, manifests.stdout + manifests.stderr
    assert "bundle-shard" in manifests.stdout

    gone = mission(f"s3://{BUCKET}/maps/missing.osm.pbf")
    path.write_text(json.dumps(gone))
    done = sadesim_cmd(sadesim, "run", str(path), "--out", str(tmp_path / "runs"), "-q", "--no-mavlink",
                       "--asset-cache", cache)
    assert done.returncode == 2, done.stdout + done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "spec.world.osm.file" in lines[0] and "missing.osm.pbf" in lines[0], done.stderr
