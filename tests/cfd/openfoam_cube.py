#!/usr/bin/env python3
"""The classic surface-mounted cube in OpenFOAM (issue 17's CFD reference): writes a case,
runs it, and prints the recirculation (reattachment) length behind the cube.

    python tests/cfd/openfoam_cube.py OUTDIR [--cells-per-h 14] [--max-iterations 2000]
    python tests/cfd/openfoam_cube.py OUTDIR --unsteady [--model kOmegaSST] [--cells-per-h 10]
        [--max-co 3] [--outer-correctors 2] [--spin-up 60] [--window 60]

Prints one JSON line: {"reattachment_H", "cells", "iterations", "converged",
"residuals", "wall_s", "openfoam"}; with --unsteady also "unsteady": true, the model,
the averaging window and the shedding seen at a probe (below). Exit status 0 means the run
finished and a reattachment point was found; the solver's logs stay in OUTDIR/case/log.*.

Reference: Martinuzzi, R. & Tropea, C. (1993), "The flow around surface-mounted, prismatic
obstacles placed in a fully developed channel flow", J. Fluids Eng. 115(1), 85-92: a cube
of height H in a channel of height 2H, Reynolds number 40 000 on H and the bulk velocity;
the flow reattaches 1.61 H behind the cube's leeward face. Steady RANS puts it further
downstream: the measured mean bubble is shortened by vortex shedding, which a steady
solution does not have (Iaccarino, Ooi, Durbin & Behnia 2003, Int. J. Heat Fluid Flow
24, 147-156: no steady RANS of the cube matched the experiment; unsteady RANS did).

Setup (lengths in cube heights H = 1 m; x streamwise, y spanwise, z up; the cube spans
x in [0, 1], y in [-0.5, 0.5], z in [0, 1]):

- Domain: the experiment's channel, height 2H, from 3H upstream of the cube to 7H behind
  its leeward face. Only the half y >= 0 is meshed, with a symmetry plane at y = 0: the
  mean flow of a steady RANS solution is symmetric, and halving the cells buys a finer
  mesh. The side at y = 3.5H is a symmetry plane (the experiment's channel is 25H wide; a
  7H wide channel blocks 7 % of its section with the cube).
- Mesh: blockMesh alone (no snappyHexMesh: the cube is a hole of the block structure, so
  its faces are exact and meshing takes a second). Cells of H/N (N = --cells-per-h,
  default 14) around the cube, growing geometrically away from it, by at most 15 % a
  cell upstream and sideways and 4 % a cell downstream (the recirculation zone needs the
  resolution: cells are at most about H/5 where the flow reattaches). N uniform layers
  per H in height: the first cell centre is at H/2N, y+ 50-100 at the walls, the
  range of wall functions. N = 10, 12, 14, 20 give 2.62, 2.57, 2.54, 2.52 H; a
  downstream growth of 1 % instead of 4 % changes N = 14's by 0.002 H.
- Turbulence: standard k-epsilon (Launder & Spalding) with wall functions (nutkWallFunction,
  epsilonWallFunction, kqRWallFunction) on the ground, the cube and the channel lid.
  Of the steady models tried it is the closest to the experiment (N = 10: standard
  2.6 H, realizable k-epsilon 3.9 H, RNG k-epsilon 3.7 H, k-omega SST 3.8 H with a
  uniform inlet omega): its
  known excess of turbulence at the windward stagnation point mixes the wake more,
  standing in for the missing shedding.
- Inlet: fully developed channel flow as in the experiment, written as profiles over z
  (fixedProfile): U from the 1/7 power law from both walls with bulk velocity 1 m/s;
  k falls linearly from its equilibrium value at the wall (u_tau^2 / sqrt(C_mu)) to
  0.8 u_tau^2 at the centre (the channel DNS value); epsilon = C_mu^0.75 k^1.5 / l with
  Nikuradse's mixing length l; u_tau from Dean's friction law. A precursor channel run
  would be more exact, but the result hardly depends on it: doubling k at the inlet
  moves the reattachment by 0.01 H.
- Outlet: p = 0, zero gradient for the rest (inletOutlet against backflow).
- Lid at z = 2H: a wall, as the experiment's channel (a slip lid gives 2.69 H instead of
  2.62 H at N = 10).
- Solver: simpleFoam, SIMPLEC, linearUpwind (second order) for U, k and epsilon (upwind
  for k and epsilon smears the shear layer's turbulence and gives 3.2 H at N = 10), at
  most --max-iterations iterations; it stops earlier when every initial residual is
  below 1e-4 (p) and 1e-5 (U, k, epsilon) (residualControl). Converging further, to
  1e-6 and 1e-7, moves the reattachment by less than 1e-4 H.
- Reattachment: along the row of cell centres nearest the symmetry plane (y = 0, the
  cube's centreline) and nearest the ground (the first cell centre, z = H/2N), the last
  point behind the leeward face where U_x < 0; the zero crossing between it and the next
  cell downstream is interpolated linearly. Measured from the leeward face, in H.

Unsteady RANS (--unsteady), for the shedding that steady RANS lacks:

- Domain: the full channel, y from -3.5H to 3.5H (the half mesh mirrored, symmetry
  planes only at the two sides): shedding is antisymmetric about y = 0.
- Start: the steady solution above (simpleFoam, standard k-epsilon, on the full mesh)
  becomes time 0, so the spin-up starts from a bubble of the right size. The fields the
  unsteady model has and k-epsilon has not are derived from it (v2 = 2/3 k, f = 0,
  omega = epsilon / (C_mu k)). A steady solution on a mirrored mesh is symmetric, and only
  round-off would break the symmetry; a lateral velocity of 0.1 m/s in the wake (2H to 5H
  downstream of the cube's front, |y| < 1.5H, z < 1.5H) at time 0 kicks the
  antisymmetric mode instead.
- Solver: pimpleFoam, second-order backward time stepping, linearUpwind as the steady
  case, the time step set by the Courant number (adjustTimeStep, --max-co, default 3) with
  --outer-correctors (default 2) PIMPLE outer iterations a step, SIMPLEC pressure
  correction and under-relaxation 0.9 on all but the last outer iteration.
- Turbulence: --model kOmegaSST (the default), v2f (Durbin's, with v2WallFunction and
  fWallFunction) or kEpsilon; the model constants are OpenFOAM's defaults. Of the three,
  only k-omega SST sheds strongly at 10 cells per H (docs/wind-cfd.md has the numbers):
  standard k-epsilon damps the kick, v2f with wall functions sheds weakly.
- Mean: fieldAverage accumulates UMean from --spin-up (s) over --window (s), weighted by
  the time step. With a bulk velocity of 1 m/s and H = 1 m, a Strouhal number near 0.1
  is a period near 10 s; k-omega SST's shedding grows to its full amplitude by about 80 s,
  hence the default 60 s of spin-up and 60 s (six periods) of averaging. UMean is written at the window's middle and end, so the means
  over its first and second halves both follow; their reattachments show whether the
  mean has settled. The reattachment is computed from UMean as the steady case's from U,
  on the cell row nearest y = 0 on the side y >= 0 (y = H/2N for an even N, the same row
  as the half domain's) and, as a check, on its mirror (y = -H/2N).
- Shedding: a probe 2H behind the leeward face on the centreline at z = H/2 records U
  every step; the lateral velocity U_y there is zero in a symmetric flow. Its period is
  the mean interval between upward crossings of its mean over the window.

OpenFOAM: Debian's `openfoam` package (v1912), run with one process. The environment is
its etc/bashrc's minimum, WM_PROJECT_DIR (default /usr/share/openfoam, Debian's path).
"""
import argparse
import json
import pathlib
import shutil
import sys
import time

from cube_case import openfoam_version, reattachment_length, run_steady, solution_fields
from cube_transient import TRANSIENT_MODELS, run_unsteady


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("outdir", type=pathlib.Path, help="folder for the case (case/ is replaced)")
    parser.add_argument("--cells-per-h", type=int, default=None,
                        help="cells per cube height near the cube (14; 10 with --unsteady)")
    parser.add_argument("--max-iterations", type=int, default=2000, help="SIMPLE iterations at most")
    parser.add_argument("--unsteady", action="store_true",
                        help="then unsteady RANS (pimpleFoam) on the full domain, from the steady solution")
    parser.add_argument("--model", choices=sorted(TRANSIENT_MODELS), default="kOmegaSST",
                        help="turbulence model of the unsteady run")
    parser.add_argument("--max-co", type=float, default=3.0, help="largest Courant number (unsteady)")
    parser.add_argument("--outer-correctors", type=int, default=2, help="PIMPLE outer correctors (unsteady)")
    parser.add_argument("--spin-up", type=float, default=60.0, help="s simulated before averaging (unsteady)")
    parser.add_argument("--window", type=float, default=60.0, help="s of averaging (unsteady)")
    args = parser.parse_args()
    if args.cells_per_h is None:
        args.cells_per_h = 10 if args.unsteady else 14

    if shutil.which("simpleFoam") is None:
        raise SystemExit("simpleFoam not found: install OpenFOAM (Debian: apt-get install openfoam)")
    case = args.outdir / "case"
    if case.exists():
        shutil.rmtree(case)
    case.mkdir(parents=True)
    start = time.monotonic()
    if args.unsteady:
        result = run_unsteady(args, case, start)
        print(json.dumps(result))
        if result["reattachment_H"] is None:
            sys.exit("no reversed flow behind the cube")
        return
    centres, velocity, log = run_steady(case, args.cells_per_h, args.max_iterations)
    wall_s = time.monotonic() - start
    result = {
        "reattachment_H": reattachment_length(centres, velocity),
        **solution_fields(centres, args.cells_per_h, log),
        "wall_s": round(wall_s, 1),
        "openfoam": openfoam_version(case),
    }
    print(json.dumps(result))
    if result["reattachment_H"] is None:
        sys.exit("no reversed flow behind the cube")


if __name__ == "__main__":
    main()
