#!/usr/bin/env python3
"""The vectorised CPU peer of issue 20, rerun side by side with `sadesim bench`: crazyflow
(JAX + MuJoCo on the CPU) at 1 kHz physics with its 100 Hz state controller, the setup of
the issue's table, as a new user would run it. Prints drone-steps per wall second.

    python3 -m venv /tmp/cf && /tmp/cf/bin/pip install crazyflow==0.4.0
    /tmp/cf/bin/python tests/bench/peer_crazyflow.py --drones 32 256 1024 --repeat 3

Each measurement: build the simulation, step it once to compile (JAX's jit), then time
`--seconds` of simulated flight in calls of `--steps-per-call` steps (default 10: a new
state command, hover at 1 m, every 10 ms, as a pilot at 100 Hz would send; a larger value
such as 1000 gives the peer its best case, fewer Python calls); the array is ready
(block_until_ready) before the clock stops. Not part of CI: a documented comparison
(docs/performance.md).
"""
import argparse
import statistics
import time

import jax
import jax.numpy as jnp
from crazyflow.control import Control
from crazyflow.sim import Sim

PHYSICS_HZ = 1000


def rate(drones: int, seconds: float, per_call: int) -> float:
    sim = Sim(n_worlds=1, n_drones=drones, control=Control.state, freq=PHYSICS_HZ, state_freq=100)
    sim.reset()
    # State command [x, y, z, vx, vy, vz, ax, ay, az, qx, qy, qz, qw, wx, wy, wz]: hover
    # at 1 m, level.
    cmd = jnp.zeros((1, drones, 16)).at[..., 2].set(1.0).at[..., 12].set(1.0)
    sim.state_control(cmd)
    sim.step(per_call)  # compile
    jax.block_until_ready(sim.data.states.pos)
    calls = max(1, int(seconds * PHYSICS_HZ / per_call))
    start = time.perf_counter()
    for _ in range(calls):
        sim.state_control(cmd)
        sim.step(per_call)
    jax.block_until_ready(sim.data.states.pos)
    wall = time.perf_counter() - start
    return drones * calls * per_call / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--drones", type=int, nargs="+", default=[32, 256, 1024])
    parser.add_argument("--seconds", type=float, default=5.0, help="simulated seconds timed")
    parser.add_argument("--steps-per-call", type=int, default=10)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    for n in args.drones:
        rates = [rate(n, args.seconds, args.steps_per_call) for _ in range(args.repeat)]
        print(f"crazyflow: {n} drones, {args.steps_per_call} steps per call: "
              f"{statistics.median(rates):.0f} drone-steps/s (median of {args.repeat}: "
              + ", ".join(f"{r:.0f}" for r in rates) + ")", flush=True)


if __name__ == "__main__":
    main()
