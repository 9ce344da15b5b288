"""The example pilots (examples/pilots/) fly their example scenarios end to end, started by
`sadesim run` as a user would run them: every drone takes off, flies and lands, and the
pilot exits 0.

The MAVLink ports are fixed: these tests must not run in parallel with the other interop
tests or any other run using MAVLink (see simrun.py).
"""
import json

import pytest

from simrun import run_piloted


@pytest.mark.parametrize("example", ["quickstart-pymavlink", "quickstart-mavsdk"])
def test_example_pilot_flies_every_drone_home(repo, sadesim, venv_bin, tmp_path, example):
    # Pilot flights take about 1.5 min of wall time at the scenario's 2x clock.
    code, out_dir, context = run_piloted(sadesim, repo / "examples" / f"{example}.yaml", tmp_path, venv_bin, 420)
    assert code is not None, f"{example}: still running after 7 minutes\n{context}"
    assert code == 0, f"{example}: sadesim exited with {code}\n{context}"
    pilot = json.loads((out_dir / "pilot.json").read_text())
    assert pilot["exitCode"] == 0, f"{example}: the pilot {pilot}\n{context}"
    summary = json.loads((out_dir / "summary.json").read_text())
    for drone in summary["perDrone"]:
        assert drone["tookOff"] and drone["landed"] and not drone["crashed"], f"{example}: {drone}\n{context}"
        assert drone["distanceM"] > 400, f"{example}: {drone}\n{context}"
    assert summary["airborne"] == 0 and summary["crashed"] == 0, f"{example}: {summary}\n{context}"
