"""Browser-side cost of the live view: frames per second Chromium draws the live view of a
quickstart fleet of N drones (Debian's Chromium through playwright-core, WebGL on
SwiftShader: the CPU, as on this machine; a desktop GPU draws far more).

    .venv/bin/python tests/bench/view_fps.py 32 1000      # results in docs/performance.md

For each N: the quickstart (`examples/quickstart.yaml`) with N drones, in real time, with
the view on; once the drones fly, the page's requestAnimationFrame rate over 10 s, and the
run's real-time factor from its progress (the simulation shares the 2 cores).
"""
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import tempfile

import yaml

REPO = pathlib.Path(__file__).resolve().parents[2]
SADESIM = os.environ.get("SADESIM", str(REPO / "target" / "release" / "sadesim"))
FPS = """new Promise((done) => {
  let frames = 0;
  const t0 = performance.now();
  const tick = () => {
    frames += 1;
    if (performance.now() - t0 < 10000) requestAnimationFrame(tick);
    else done({fps: frames / ((performance.now() - t0) / 1000), drones: window.sadesimView.positions().length,
               simTime: window.sadesimView.time});
  };
  requestAnimationFrame(tick);
})"""


def measure(drones: int, tmp: pathlib.Path) -> dict:
    doc = yaml.safe_load((REPO / "examples" / "quickstart.yaml").read_text())
    spec = doc["spec"]
    spec["clock"] = {"mode": "realtime"}
    spec["duration"] = "2m"
    spec["rendering"] = {"enabled": True}
    spec["fleet"][0]["count"] = drones
    spec["fleet"][0]["homes"]["randomInArea"]["radiusM"] = 240
    scenario = tmp / f"view-{drones}.yaml"
    scenario.write_text(yaml.safe_dump(doc))
    proc = subprocess.Popen([SADESIM, "run", str(scenario), "--out", str(tmp / "runs"), "--no-mavlink"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, cwd=tmp)
    try:
        for line in proc.stderr:
            m = re.search(r"live view: (http://\S+)", line)
            if m:
                url = m.group(1)
                break
        steps = {"url": url, "outDir": str(tmp), "steps": [
            {"waitFor": "window.sadesimView && window.sadesimView.ready && window.sadesimView.time > 15", "timeoutMs": 180000},
            {"eval": FPS},
        ]}
        config = tmp / f"steps-{drones}.json"
        config.write_text(json.dumps(steps))
        done = subprocess.run(["node", str(REPO / "tests" / "browser" / "drive.mjs"), str(config)],
                              capture_output=True, text=True, timeout=600, check=True)
        return json.loads(done.stdout)["results"][-1]["value"]
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        for n in [int(a) for a in sys.argv[1:]] or [32, 1000]:
            r = measure(n, pathlib.Path(tmp))
            print(f"{n} drones: {r['fps']:.1f} frames/s in Chromium (SwiftShader), {r['drones']} drones drawn at sim time {r['simTime']:.1f} s")
