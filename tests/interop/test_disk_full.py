"""The disk filling in the middle of a recording (issue 40): runs recorded onto a small tmpfs.

What must hold: the run ends with an error naming the file that could not be written (and
a non-zero exit code); what was written before opens in its readers (`recording.mcap` in
the `mcap` package's reader, with its summary; every ULog in pyulog); `manifest.json` says
which files are incomplete and how; and `sadesim archive verify` reports the
incompleteness, file by file, rather than a checksum error.

Needs root (or CAP_SYS_ADMIN) to mount a tmpfs; skipped with the reason where that fails.
"""
import copy
import glob
import json
import os
import pathlib
import subprocess
import warnings

import pytest
import yaml
from mcap.reader import make_reader
from pyulog import ULog

REPO = pathlib.Path(__file__).resolve().parents[2]
QUICKSTART = REPO / "examples" / "quickstart.yaml"
RESERVE = ".sadesim-disk-reserve"


@pytest.fixture
def small_disk(tmp_path):
    """`small_disk(mib)` -> the folder of a fresh tmpfs of `mib` MiB, unmounted at teardown."""
    mounted = []

    def mount(mib):
        point = tmp_path / f"disk-{len(mounted)}"
        point.mkdir()
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={mib}m", "tmpfs", str(point)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            reason = f"cannot mount a tmpfs (needs root): {done.stderr.strip()}"
            warnings.warn(reason, stacklevel=1)
            pytest.skip(reason)
        mounted.append(point)
        return point

    try:
        yield mount
    finally:
        for point in reversed(mounted):
            subprocess.run(["umount", "-l", str(point)], check=False)


def run_onto(sadesim, out, doc, *flags):
    """`sadesim run` of `doc` into `out` with `flags`; (exit code, stdout + stderr, the run
    folder)."""
    scenario = out.parent / f"{out.name}-{doc['metadata']['name']}.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    done = subprocess.run([sadesim, "run", str(scenario), "--out", str(out), "-q", "--no-mavlink", *flags],
                          capture_output=True, text=True, timeout=120, cwd=REPO)
    folders = glob.glob(str(out / doc["metadata"]["name"] / "*"))
    assert len(folders) == 1, (folders, done.stdout, done.stderr)
    return done.returncode, done.stdout + done.stderr, pathlib.Path(folders[0])


def quickstart(name, recording=None):
    doc = copy.deepcopy(yaml.safe_load(QUICKSTART.read_text()))
    doc["metadata"]["name"] = name
    if recording is not None:
        doc["spec"]["recording"] = recording
    return doc


def verify(sadesim, folder):
    done = subprocess.run([sadesim, "archive", "verify", str(folder), "--quiet"],
                          capture_output=True, text=True, timeout=60)
    return done.returncode, done.stdout + done.stderr


def check_incomplete(sadesim, folder, output):
    """What every run the disk stopped holds; returns (manifest's `incomplete`, the file
    that could not be written)."""
    manifest = json.loads((folder / "manifest.json").read_text())
    incomplete = manifest["incomplete"]
    failed = incomplete["reason"].split(":")[0]
    assert "No space left on device" in incomplete["reason"], incomplete
    # The CLI names the file (and says why) and exits non-zero.
    assert f"{failed}: No space left on device" in output, output
    assert not (folder / RESERVE).exists(), "the reserve is given back"
    assert not (folder / ".manifest.json.tmp").exists()
    states = {f["path"]: f["state"] for f in incomplete["files"]}
    assert set(states.values()) <= {"truncated", "notFinalised", "notWritten"}, states
    assert states.get(failed) in ("truncated", "notFinalised"), states
    listed = {f["path"] for f in manifest["files"]}
    for path, state in states.items():
        assert (path in listed) == (state != "notWritten"), (path, state)
    # The summary was written, and says why the run ended.
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["endReason"].startswith(f"recordingFailed: {failed}: "), summary["endReason"]
    assert 0 < summary["simTimeS"] < 180
    # No report on a full disk: what room there is goes to the manifest.
    assert not (folder / "report.html").exists()
    # verify: the reason, then each file; no checksum error.
    code, said = verify(sadesim, folder)
    assert code != 0, said
    assert "the run's recording stopped on a write error: " + incomplete["reason"] in said, said
    for path, state in states.items():
        assert f"{path}: incomplete ({state}): " in said, said
    assert "sha256 mismatch" not in said and "not in the manifest" not in said and "missing" not in said, said
    return incomplete, failed


@pytest.mark.parametrize("flags", [[], ["--processes"]], ids=["threads", "processes"])
def test_a_disk_that_fills_mid_run_keeps_every_recording_readable(sadesim, small_disk, flags):
    """Quickstart's 14 MB onto 8 MiB: the disk fills about a third into the run. With
    `--processes` the coordinator process records, as the coordinator pod does, and the CLI
    passes its error on."""
    disk = small_disk(8)
    code, output, folder = run_onto(sadesim, disk, quickstart("disk-full"), *flags)
    assert code != 0, output
    incomplete, failed = check_incomplete(sadesim, folder, output)
    states = {f["path"]: f["state"] for f in incomplete["files"]}
    stopped_s = json.loads((folder / "summary.json").read_text())["simTimeS"]
    ulogs = sorted(glob.glob(str(folder / "ulog" / "*.ulg")))
    assert len(ulogs) == 4
    for path in ["recording.mcap", "events.jsonl", "trajectory.csv"] + [f"ulog/{pathlib.Path(u).name}" for u in ulogs]:
        assert states[path] == "truncated", (path, states)

    # recording.mcap: the seeking reader reads its summary and every message it counts.
    with open(folder / "recording.mcap", "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary().statistics
        read = sum(1 for _ in reader.iter_messages())
    assert read == stats.message_count > 10_000
    assert 10 < stats.message_end_time / 1e9 <= stopped_s + 0.01

    # Every ULog opens in pyulog, whole, with samples up to where the recording stopped.
    for path in ulogs:
        log = ULog(path)
        assert not log.file_corruption, path
        last_s = max(d.data["timestamp"][-1] for d in log.data_list) / 1e6
        assert 10 < last_s <= stopped_s + 0.01, (path, last_s)

    # The CSV ends on a whole line.
    assert (folder / "trajectory.csv").read_bytes().endswith(b"\n")
    for line in (folder / "events.jsonl").read_text().splitlines():
        json.loads(line)


def test_the_trajectory_filling_the_disk_is_named(sadesim, small_disk):
    """No MCAP or ULog: `trajectory.csv` (or `events.jsonl`) is what fills the disk, and
    the error and the manifest name it."""
    disk = small_disk(4)
    code, output, folder = run_onto(sadesim, disk, quickstart("csv-full", {"mcap": False, "ulog": False}))
    assert code != 0, output
    incomplete, failed = check_incomplete(sadesim, folder, output)
    assert failed in ("trajectory.csv", "events.jsonl"), incomplete
    assert (folder / "trajectory.csv").read_bytes().endswith(b"\n")


def test_a_disk_without_room_for_the_reserve_is_refused_at_the_start(sadesim, small_disk):
    """Less room than the run sets aside to close its files: refused before the first
    window, naming the reserve and the room it wanted."""
    disk = small_disk(2)
    code, output, folder = run_onto(sadesim, disk, quickstart("no-room"))
    assert code != 0, output
    assert f"{RESERVE}: setting aside" in output and "No space left on device" in output, output
    assert not (folder / RESERVE).exists()
    assert not (folder / "recording.mcap").exists()
