"""The example pilots (examples/pilots/) fly their example scenarios end to end, started by
`sadesim run` as a user would run them: every drone takes off, flies and lands, and the
pilot exits 0.

The MAVLink ports are fixed: these tests must not run in parallel with the other interop
tests or any other run using MAVLink (see simrun.py).
"""
import json
import os
import signal
import subprocess

import pytest


@pytest.mark.parametrize("example", ["quickstart-pymavlink", "quickstart-mavsdk"])
def test_example_pilot_flies_every_drone_home(repo, sadesim, venv_bin, tmp_path, example):
    env = dict(os.environ)
    env["PATH"] = f"{venv_bin}{os.pathsep}{env.get('PATH', '')}"  # the scenario's `python3` is the venv's
    log = tmp_path / "sadesim.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [sadesim, "run", str(repo / "examples" / f"{example}.yaml"), "--out", str(tmp_path), "-q"],
            stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env, start_new_session=True,
        )
        try:
            # Pilot flights take about 1.5 min of wall time at the scenario's 2x clock.
            code = proc.wait(timeout=420)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                pass
            code = None
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()

    (out_dir,) = list((tmp_path / example).glob("*")) or [None]
    pilot_log = (out_dir / "pilot.log").read_text(errors="replace") if out_dir and (out_dir / "pilot.log").exists() else ""
    context = f"--- sadesim ---\n{log.read_text(errors='replace')[-3000:]}\n--- pilot.log ---\n{pilot_log[-4000:]}"
    assert code is not None, f"{example}: still running after 7 minutes\n{context}"
    assert code == 0, f"{example}: sadesim exited with {code}\n{context}"
    pilot = json.loads((out_dir / "pilot.json").read_text())
    assert pilot["exitCode"] == 0, f"{example}: the pilot {pilot}\n{context}"
    summary = json.loads((out_dir / "summary.json").read_text())
    for drone in summary["perDrone"]:
        assert drone["tookOff"] and drone["landed"] and not drone["crashed"], f"{example}: {drone}\n{context}"
        assert drone["distanceM"] > 400, f"{example}: {drone}\n{context}"
    assert summary["airborne"] == 0 and summary["crashed"] == 0, f"{example}: {summary}\n{context}"
