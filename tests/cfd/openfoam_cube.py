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
import math
import os
import pathlib
import re
import shutil
import subprocess
import sys
import time

import numpy as np

H = 1.0  # cube height, m
U_BULK = 1.0  # bulk velocity of the channel, m/s
RE_H = 40_000.0  # Reynolds number on H and U_BULK, as Martinuzzi & Tropea
NU = U_BULK * H / RE_H  # kinematic viscosity, m^2/s
C_MU = 0.09
KAPPA = 0.41

UPSTREAM = 3.0 * H  # inlet to windward face, m
DOWNSTREAM = 7.0 * H  # leeward face to outlet, m
HALF_WIDTH = 3.5 * H  # symmetry plane to side, m
CHANNEL = 2.0 * H  # channel height, m
# Largest ratio of neighbouring cell sizes: upstream, sideways; and downstream of the cube.
GROWTH = 1.15
GROWTH_DOWNSTREAM = 1.04

# The solver stops when every initial residual is below these (SIMPLE residualControl).
RESIDUAL_TARGETS = {"p": 1e-4, "U": 1e-5, "k": 1e-5, "epsilon": 1e-5}

HEADER = """FoamFile
{{
    version     2.0;
    format      ascii;
    class       {cls};
    object      {obj};
}}
"""


def foam_file(cls, obj, body):
    return HEADER.format(cls=cls, obj=obj) + body


def graded(length, fine, max_growth, fine_at_start):
    """(cells, blockMesh expansion ratio) for a segment of `length` m whose cell at one end
    is `fine` m and which grows geometrically by at most `max_growth` a cell.

    The growth q solves fine * (q^n - 1) / (q - 1) = length for the smallest n that keeps
    q <= max_growth; blockMesh's expansion ratio is last cell / first cell = q^(n-1).
    """
    if length <= fine * 1.000001:
        return 1, 1.0
    n = 1
    while True:
        n += 1
        if n * fine >= length:
            q = 1.0
            break
        lo, hi = 1.0, 10.0  # bisection on q: the series sum grows with q
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            if fine * (mid**n - 1.0) / (mid - 1.0) < length:
                lo = mid
            else:
                hi = mid
        q = 0.5 * (lo + hi)
        if q <= max_growth:
            break
    ratio = q ** (n - 1)
    return n, (ratio if fine_at_start else 1.0 / ratio)


def block_mesh_dict(n_h, full=False):
    """blockMeshDict: the half channel cut into 3 x 2 x 2 blocks, the cube's block left out;
    with `full`, the whole channel (y from -HALF_WIDTH to HALF_WIDTH) in 3 x 3 x 2 blocks,
    mirrored about y = 0, with no centre plane: vortex shedding is antisymmetric, so an
    unsteady run cannot use the symmetry plane.
    """
    h = H / n_h
    xs = [-UPSTREAM, 0.0, H, H + DOWNSTREAM]
    zs = [0.0, H, CHANNEL]
    # Cells and expansion ratio of each segment between consecutive coordinates.
    xseg = [graded(UPSTREAM, h, GROWTH, False), (n_h, 1.0), graded(DOWNSTREAM, h, GROWTH_DOWNSTREAM, True)]
    side = graded(HALF_WIDTH - 0.5 * H, h, GROWTH, True)
    if full:
        ys = [-HALF_WIDTH, -0.5 * H, 0.5 * H, HALF_WIDTH]
        # The far side grows away from the cube too: the same segment, graded the other way.
        yseg = [(side[0], 1.0 / side[1]), (n_h, 1.0), side]
        cube = (1, 1, 0)
    else:
        ys = [0.0, 0.5 * H, HALF_WIDTH]
        yseg = [(max(1, round(0.5 * n_h)), 1.0), side]
        cube = (1, 0, 0)
    zseg = [(n_h, 1.0), (n_h, 1.0)]
    nj_blocks = len(ys) - 1
    per_layer = 4 * len(ys)  # vertices in one z plane

    def vid(i, j, k):
        return i + 4 * (j + len(ys) * k)

    vertices = [f"    ({x:g} {y:g} {z:g})" for z in zs for y in ys for x in xs]
    blocks = []
    # The side at y = HALF_WIDTH; in the full domain sideNeg is the one at y = -HALF_WIDTH
    # (a symmetryPlane patch must be planar).
    patches = {"inlet": [], "outlet": [], "ground": [], "lid": [], "centre": [], "side": [], "cube": []}
    if full:
        patches["sideNeg"] = []
    # Outward faces of a hex by its local vertices (OpenFOAM's hex model), with the
    # neighbouring block's offset and the boundary patch if that neighbour is outside.
    faces = [
        ((0, 4, 7, 3), (-1, 0, 0), "inlet"),
        ((1, 2, 6, 5), (1, 0, 0), "outlet"),
        ((0, 1, 5, 4), (0, -1, 0), "sideNeg" if full else "centre"),
        ((3, 7, 6, 2), (0, 1, 0), "side"),
        ((0, 3, 2, 1), (0, 0, -1), "ground"),
        ((4, 5, 6, 7), (0, 0, 1), "lid"),
    ]
    for k in range(2):
        for j in range(nj_blocks):
            for i in range(3):
                if (i, j, k) == cube:
                    continue
                corners = [vid(i, j, k), vid(i + 1, j, k), vid(i + 1, j + 1, k), vid(i, j + 1, k)]
                corners += [c + per_layer for c in corners]
                (nx, gx), (ny, gy), (nz, gz) = xseg[i], yseg[j], zseg[k]
                blocks.append(
                    f"    hex ({' '.join(map(str, corners))}) ({nx} {ny} {nz}) "
                    f"simpleGrading ({gx:.6g} {gy:.6g} {gz:.6g})"
                )
                for local, (di, dj, dk), outside in faces:
                    ni, nj, nk = i + di, j + dj, k + dk
                    if (ni, nj, nk) == cube:
                        patch = "cube"
                    elif 0 <= ni < 3 and 0 <= nj < nj_blocks and 0 <= nk < 2:
                        continue  # an internal face between two blocks
                    else:
                        patch = outside
                    patches[patch].append("(" + " ".join(str(corners[v]) for v in local) + ")")
    if full:
        del patches["centre"]
    kinds = {"inlet": "patch", "outlet": "patch", "ground": "wall", "lid": "wall", "cube": "wall",
             "centre": "symmetryPlane", "side": "symmetryPlane", "sideNeg": "symmetryPlane"}
    boundary = []
    for name, fs in patches.items():
        boundary.append(f"    {name}\n    {{\n        type {kinds[name]};\n        faces\n        (\n"
                        + "".join(f"            {f}\n" for f in fs) + "        );\n    }")
    cells = (sum(a[0] * b[0] * c[0] for a in xseg for b in yseg for c in zseg)
             - xseg[cube[0]][0] * yseg[cube[1]][0] * zseg[cube[2]][0])
    text = (f"scale 1;\n\nvertices\n(\n{chr(10).join(vertices)}\n);\n\nblocks\n(\n{chr(10).join(blocks)}\n);\n\n"
            f"edges ();\n\nboundary\n(\n{chr(10).join(boundary)}\n);\n\nmergePatchPairs ();\n")
    return foam_file("dictionary", "blockMeshDict", text), cells


def inlet_profiles(samples=81):
    """Fully developed channel flow over z in [0, 2H]: tables (z, U_x), (z, k), (z, epsilon)."""
    # Dean (1978): c_f = 0.073 Re_m^-1/4, Re_m on the bulk velocity and the full height.
    re_m = U_BULK * CHANNEL / NU
    u_tau = U_BULK * math.sqrt(0.5 * 0.073 * re_m**-0.25)
    half = 0.5 * CHANNEL
    u_centre = U_BULK * 8.0 / 7.0  # the 1/7 power law's mean is 7/8 of its centre value
    rows = []
    for z in np.linspace(0.0, CHANNEL, samples):
        d = max(min(z, CHANNEL - z), 1e-3 * half)  # distance to the nearer wall, m
        eta = d / half
        u = u_centre * eta ** (1.0 / 7.0)
        k = u_tau**2 * ((1.0 - eta) / math.sqrt(C_MU) + 0.8 * eta)
        # Nikuradse's mixing length for pipes and channels; -> kappa d at the wall.
        mix = half * (0.14 - 0.08 * (1.0 - eta) ** 2 - 0.06 * (1.0 - eta) ** 4)
        eps = C_MU**0.75 * k**1.5 / mix
        rows.append((z, u, k, eps))
    return rows, u_tau


def table(rows, column, vector=False):
    entries = []
    for r in rows:
        v = f"({r[column]:.6g} 0 0)" if vector else f"{r[column]:.6g}"
        entries.append(f"({r[0]:.6g} {v})")
    return "table (" + " ".join(entries) + ")"


def write_case(case, n_h, max_iterations, full=False):
    """The steady case (simpleFoam, standard k-epsilon) on the half domain, or with `full`
    on the whole one (the start of an unsteady run)."""
    for d in ("0", "constant", "system"):
        (case / d).mkdir(parents=True, exist_ok=True)
    mesh, _ = block_mesh_dict(n_h, full)
    (case / "system" / "blockMeshDict").write_text(mesh)
    rows, _ = inlet_profiles()
    k_mid = rows[len(rows) // 2][2]
    eps_mid = rows[len(rows) // 2][3]

    def profile(table_text):
        return f"type fixedProfile; profile {table_text}; direction (0 0 1); origin 0;"

    walls = {"ground", "lid", "cube"}
    symmetric = "side|sideNeg" if full else "centre|side"

    def field(cls, obj, dims, internal, inlet, wall, outlet):
        parts = [f"dimensions {dims};\n\ninternalField uniform {internal};\n\nboundaryField\n{{\n",
                 f"    inlet {{ {inlet} }}\n", f"    outlet {{ {outlet} }}\n",
                 f"    \"({'|'.join(sorted(walls))})\" {{ {wall} }}\n",
                 f"    \"({symmetric})\" {{ type symmetryPlane; }}\n", "}\n"]
        (case / "0" / obj).write_text(foam_file(cls, obj, "".join(parts)))

    field("volVectorField", "U", "[0 1 -1 0 0 0 0]", "(1 0 0)", profile(table(rows, 1, vector=True)),
          "type noSlip;", "type inletOutlet; inletValue uniform (0 0 0); value uniform (1 0 0);")
    field("volScalarField", "p", "[0 2 -2 0 0 0 0]", "0", "type zeroGradient;", "type zeroGradient;",
          "type fixedValue; value uniform 0;")
    field("volScalarField", "k", "[0 2 -2 0 0 0 0]", f"{k_mid:.6g}", profile(table(rows, 2)),
          f"type kqRWallFunction; value uniform {k_mid:.6g};",
          f"type inletOutlet; inletValue uniform {k_mid:.6g}; value uniform {k_mid:.6g};")
    field("volScalarField", "epsilon", "[0 2 -3 0 0 0 0]", f"{eps_mid:.6g}", profile(table(rows, 3)),
          f"type epsilonWallFunction; value uniform {eps_mid:.6g};",
          f"type inletOutlet; inletValue uniform {eps_mid:.6g}; value uniform {eps_mid:.6g};")
    field("volScalarField", "nut", "[0 2 -1 0 0 0 0]", "0", "type calculated; value uniform 0;",
          "type nutkWallFunction; value uniform 0;", "type calculated; value uniform 0;")

    (case / "constant" / "transportProperties").write_text(foam_file(
        "dictionary", "transportProperties", f"transportModel Newtonian;\nnu {NU:.6g};\n"))
    (case / "constant" / "turbulenceProperties").write_text(foam_file(
        "dictionary", "turbulenceProperties",
        "simulationType RAS;\nRAS\n{\n    RASModel kEpsilon;\n    turbulence on;\n    printCoeffs on;\n}\n"))
    (case / "system" / "controlDict").write_text(foam_file("dictionary", "controlDict", f"""application simpleFoam;
startFrom startTime;
startTime 0;
stopAt endTime;
endTime {max_iterations};
deltaT 1;
writeControl timeStep;
writeInterval {max_iterations};
purgeWrite 0;
writeFormat ascii;
writePrecision 8;
writeCompression off;
timeFormat general;
timePrecision 6;
runTimeModifiable false;
"""))
    (case / "system" / "fvSchemes").write_text(foam_file("dictionary", "fvSchemes", """ddtSchemes { default steadyState; }
gradSchemes { default Gauss linear; grad(U) cellLimited Gauss linear 1; }
divSchemes
{
    default none;
    div(phi,U) bounded Gauss linearUpwind grad(U);
    div(phi,k) bounded Gauss linearUpwind grad(k);
    div(phi,epsilon) bounded Gauss linearUpwind grad(epsilon);
    div((nuEff*dev2(T(grad(U))))) Gauss linear;
}
laplacianSchemes { default Gauss linear corrected; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }
wallDist { method meshWave; }
"""))
    targets = "".join(f'        "{name}" {value:g};\n' for name, value in RESIDUAL_TARGETS.items())
    (case / "system" / "fvSolution").write_text(foam_file("dictionary", "fvSolution", f"""solvers
{{
    p {{ solver GAMG; smoother GaussSeidel; tolerance 1e-7; relTol 0.1; }}
    "(U|k|epsilon)" {{ solver smoothSolver; smoother symGaussSeidel; tolerance 1e-8; relTol 0.1; }}
}}
SIMPLE
{{
    nNonOrthogonalCorrectors 0;
    consistent yes;
    residualControl
    {{
{targets}    }}
}}
relaxationFactors
{{
    equations {{ U 0.9; ".*" 0.7; }}
}}
"""))


def openfoam_env():
    env = dict(os.environ)
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    # One process, and no OpenMPI warnings about running as root in containers.
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT", "1")
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
    return env


def run(case, *args):
    """Runs an OpenFOAM tool in `case`, its output in case/log.<tool>; raises on failure."""
    log = case / f"log.{args[0]}"
    env = openfoam_env()
    env["PWD"] = str(case.resolve())  # else OpenFOAM warns that PWD is not the cwd
    with open(log, "w") as out:
        proc = subprocess.run(list(args), cwd=case.resolve(), env=env, stdout=out, stderr=subprocess.STDOUT)
    if proc.returncode != 0:
        tail = log.read_text().splitlines()[-20:]
        raise SystemExit(f"{args[0]} failed (exit {proc.returncode}); the end of {log}:\n" + "\n".join(tail))


def read_vector_field(path):
    """An ASCII volVectorField's internal field as an (N, 3) array."""
    text = path.read_text()
    m = re.search(r"internalField\s+nonuniform\s+List<vector>\s*(\d+)\s*\(", text)
    if not m:
        raise SystemExit(f"{path}: expected 'internalField nonuniform List<vector> N (' (an ASCII field)")
    n = int(m.group(1))
    body = text[m.end():]
    values = re.findall(r"\(([^()]*)\)", body[: body.index(")\n;")] if ")\n;" in body else body)[:n]
    arr = np.array([[float(c) for c in v.split()] for v in values])
    if arr.shape != (n, 3):
        raise SystemExit(f"{path}: expected {n} vectors, read {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SystemExit(f"{path}: non-finite values")
    return arr


def solver_log(case):
    """(iterations, converged, last initial residual per field) from log.simpleFoam."""
    text = (case / "log.simpleFoam").read_text()
    times = re.findall(r"^Time = (\d+)$", text, re.M)
    residuals = {}
    for name, value in re.findall(r"Solving for (\w+), Initial residual = ([0-9.eE+-]+)", text):
        # U's components: the largest initial residual of Ux, Uy, Uz counts (as residualControl).
        key = "U" if name in ("Ux", "Uy", "Uz") else name
        residuals.setdefault(key, {})[name] = float(value)
    last = {k: max(v.values()) for k, v in residuals.items()}
    converged = "SIMPLE solution converged" in text
    return int(times[-1]) if times else 0, converged, last


def openfoam_version(case):
    """The version in the solver's banner ("Build  : OPENFOAM=1912 patch=200626" is v1912)."""
    m = re.search(r"^Build\s*:\s*OPENFOAM=(\d+)", (case / "log.simpleFoam").read_text(), re.M)
    return f"v{m.group(1)}" if m else "unknown"


def reattachment_length(centres, velocity, side=1.0):
    """Distance from the leeward face (x = H) to where U_x turns positive along the cube's
    centreline (the cell row nearest y = 0) at the first cell centre above the ground, in H.
    None when the flow is not reversed behind the cube.

    The row is the one nearest y = 0 on the side y >= 0 (side = 1), or y <= 0 (side = -1):
    with an even number of cells across the cube there is no row on y = 0 in the full
    domain, and the half domain's row is the first one, at y = H/2N.
    """
    ys = side * centres[:, 1]
    y_row = ys[ys > -1e-9 * H].min()
    z_row = centres[:, 2].min()
    tol = 1e-6 * H
    row = (np.abs(ys - y_row) < tol) & (np.abs(centres[:, 2] - z_row) < tol) & (centres[:, 0] > H)
    x = centres[row, 0]
    ux = velocity[row, 0]
    order = np.argsort(x)
    x, ux = x[order], ux[order]
    negative = np.nonzero(ux < 0.0)[0]
    if len(negative) == 0:
        return None
    i = negative[-1]
    if i + 1 >= len(x):
        return (x[i] - H) / H  # reversed up to the outlet: the domain is too short
    # The zero crossing between the last reversed cell and the next, linearly.
    x0 = x[i] + (x[i + 1] - x[i]) * (-ux[i]) / (ux[i + 1] - ux[i])
    return (x0 - H) / H


# --- Unsteady RANS (--unsteady) -------------------------------------------------------------

# Turbulence models the unsteady run accepts, with the fields each solves besides U and p.
TRANSIENT_MODELS = {
    "v2f": ("k", "epsilon", "v2", "f"),
    "kEpsilon": ("k", "epsilon"),
    "kOmegaSST": ("k", "omega"),
}
# The probe whose lateral velocity shows the shedding: 2H behind the leeward face, on the
# centreline (a hair off y = 0, which is a cell face), at half the cube's height. U_y there
# is zero in a symmetric flow and oscillates at the shedding frequency when vortices shed.
PROBE = (H + 2.0 * H, 1e-3 * H, 0.5 * H)
# The lateral velocity put into the wake at the start, m/s: an antisymmetric kick, so that
# shedding need not wait for round-off to break the mirrored mesh's symmetry.
KICK_UY = 0.1 * U_BULK


def internal_field_span(text):
    """(start, end) of a field file's `internalField ... ;` entry."""
    m = re.search(r"internalField\s+(uniform\s+[^;]*|nonuniform\s+List<\w+>\s*\d+\s*\(.*?\n\)\s*);", text, re.S)
    if not m:
        raise SystemExit("no internalField entry")
    return m.start(), m.end()


def read_scalar_field(path):
    """An ASCII volScalarField's internal field as an (N,) array."""
    text = path.read_text()
    m = re.search(r"internalField\s+nonuniform\s+List<scalar>\s*(\d+)\s*\((.*?)\n\)\s*;", text, re.S)
    if not m:
        raise SystemExit(f"{path}: expected 'internalField nonuniform List<scalar> N (' (an ASCII field)")
    arr = np.array(m.group(2).split(), dtype=float)
    if arr.shape != (int(m.group(1)),) or not np.all(np.isfinite(arr)):
        raise SystemExit(f"{path}: expected {m.group(1)} finite scalars, read {arr.shape}")
    return arr


def nonuniform(values):
    """An internalField entry for an (N,) or (N, 3) array."""
    if values.ndim == 1:
        body = "\n".join(f"{v:.8g}" for v in values)
        kind = "scalar"
    else:
        body = "\n".join(f"({a:.8g} {b:.8g} {c:.8g})" for a, b, c in values)
        kind = "vector"
    return f"internalField nonuniform List<{kind}> {len(values)}\n(\n{body}\n)\n;"


def prepare_transient(case, model, t_end, spin_up, window, max_co, outer, n_h):
    """Turns the converged steady case into the start of a pimpleFoam run.

    The steady solution (its last iteration's folder) becomes time 0; the fields of the
    chosen model that standard k-epsilon does not have are derived from it (v2 = 2/3 k,
    isotropic; f = 0; omega = epsilon / (C_mu k)); U gets an antisymmetric lateral kick in
    the wake (KICK_UY behind the cube, 1H to 4H downstream of the leeward face, below
    1.5H and within 1.5H of the centreline).
    """
    steady = max((d for d in case.iterdir() if re.fullmatch(r"\d+", d.name) and d.name != "0"),
                 key=lambda d: int(d.name))
    shutil.rmtree(case / "0")
    shutil.rmtree(steady / "uniform", ignore_errors=True)
    steady.rename(case / "0")
    zero = case / "0"

    centres = read_vector_field(zero / "C")
    u_text = (zero / "U").read_text()
    velocity = read_vector_field(zero / "U")
    x, y, z = centres[:, 0], centres[:, 1], centres[:, 2]
    wake = (x > 2.0 * H) & (x < 5.0 * H) & (np.abs(y) < 1.5 * H) & (z < 1.5 * H)
    velocity[wake, 1] += KICK_UY
    a, b = internal_field_span(u_text)
    (zero / "U").write_text(u_text[:a] + nonuniform(velocity) + u_text[b:])

    k = read_scalar_field(zero / "k")
    eps = read_scalar_field(zero / "epsilon")
    rows, _ = inlet_profiles()
    walls = '"(ground|lid|cube)"'

    def profile(column, scale=1.0):
        return ("type fixedProfile; profile table ("
                + " ".join(f"({r[0]:.6g} {scale * r[column]:.6g})" for r in rows)
                + "); direction (0 0 1); origin 0;")

    def scalar(obj, dims, values, inlet, wall, outlet):
        text = foam_file("volScalarField", obj, f"dimensions {dims};\n\n{nonuniform(values)}\n\nboundaryField\n{{\n"
                         f"    inlet {{ {inlet} }}\n    outlet {{ {outlet} }}\n    {walls} {{ {wall} }}\n"
                         "    \"(side|sideNeg)\" { type symmetryPlane; }\n}\n")
        (zero / obj).write_text(text)

    v2_mid = 2.0 / 3.0 * rows[len(rows) // 2][2]
    scalar("v2", "[0 2 -2 0 0 0 0]", 2.0 / 3.0 * k, profile(2, 2.0 / 3.0),
           f"type v2WallFunction; value uniform {v2_mid:.6g};",
           f"type inletOutlet; inletValue uniform {v2_mid:.6g}; value uniform {v2_mid:.6g};")
    scalar("f", "[0 0 -1 0 0 0 0]", np.zeros_like(k), "type zeroGradient;",
           "type fWallFunction; value uniform 0;", "type zeroGradient;")
    omega_rows = [(r[0], r[1], r[2], r[3] / (C_MU * r[2])) for r in rows]
    omega_mid = omega_rows[len(rows) // 2][3]
    scalar("omega", "[0 0 -1 0 0 0 0]", eps / (C_MU * k),
           "type fixedProfile; profile table (" + " ".join(f"({r[0]:.6g} {r[3]:.6g})" for r in omega_rows)
           + "); direction (0 0 1); origin 0;",
           f"type omegaWallFunction; value uniform {omega_mid:.6g};",
           f"type inletOutlet; inletValue uniform {omega_mid:.6g}; value uniform {omega_mid:.6g};")

    (case / "constant" / "turbulenceProperties").write_text(foam_file(
        "dictionary", "turbulenceProperties",
        f"simulationType RAS;\nRAS\n{{\n    RASModel {model};\n    turbulence on;\n    printCoeffs on;\n}}\n"))
    # A first step at Courant number ~0.5 with the fastest flow ~1.5 U_BULK; adjustTimeStep
    # then grows it to max_co.
    dt0 = 0.5 * (H / n_h) / (1.5 * U_BULK)
    # Writes fall on multiples of the write interval: the largest one (to the millisecond)
    # that hits the window's middle and its end, where UMean is read.
    write_ms = math.gcd(round(1000 * spin_up), round(500 * window))
    if write_ms == 0:
        raise SystemExit("--window must be at least 2 ms")
    px, py, pz = PROBE
    (case / "system" / "controlDict").write_text(foam_file("dictionary", "controlDict", f"""application pimpleFoam;
startFrom startTime;
startTime 0;
stopAt endTime;
endTime {t_end:g};
deltaT {dt0:.6g};
adjustTimeStep yes;
maxCo {max_co:g};
maxDeltaT 1;
writeControl adjustableRunTime;
writeInterval {write_ms / 1000:g};
purgeWrite 0;
writeFormat ascii;
writePrecision 8;
writeCompression off;
timeFormat general;
timePrecision 8;
runTimeModifiable false;
functions
{{
    average
    {{
        type fieldAverage;
        libs ("libfieldFunctionObjects.so");
        timeStart {spin_up:g};
        writeControl writeTime;
        fields ( U {{ mean on; prime2Mean off; base time; }} );
    }}
    probes
    {{
        type probes;
        libs ("libsampling.so");
        writeControl timeStep;
        writeInterval 1;
        fields (U);
        probeLocations (({px:g} {py:g} {pz:g}));
    }}
}}
"""))
    fields = "|".join(TRANSIENT_MODELS[model])
    # f's equation is elliptic: no convection term.
    convection = "".join(f"    div(phi,{f}) Gauss linearUpwind grad({f});\n"
                         for f in TRANSIENT_MODELS[model] if f != "f")
    (case / "system" / "fvSchemes").write_text(foam_file("dictionary", "fvSchemes", f"""ddtSchemes {{ default backward; }}
gradSchemes {{ default Gauss linear; grad(U) cellLimited Gauss linear 1; }}
divSchemes
{{
    default none;
    div(phi,U) Gauss linearUpwind grad(U);
{convection}    div((nuEff*dev2(T(grad(U))))) Gauss linear;
}}
laplacianSchemes {{ default Gauss linear corrected; }}
interpolationSchemes {{ default linear; }}
snGradSchemes {{ default corrected; }}
wallDist {{ method meshWave; }}
"""))
    (case / "system" / "fvSolution").write_text(foam_file("dictionary", "fvSolution", f"""solvers
{{
    p {{ solver GAMG; smoother GaussSeidel; tolerance 1e-6; relTol 0.05; }}
    pFinal {{ $p; relTol 0; }}
    "(U|{fields})" {{ solver smoothSolver; smoother symGaussSeidel; tolerance 1e-7; relTol 0.1; }}
    "(U|{fields})Final" {{ $U; relTol 0; }}
}}
PIMPLE
{{
    momentumPredictor yes;
    consistent yes;
    nOuterCorrectors {outer};
    nCorrectors 2;
    nNonOrthogonalCorrectors 0;
}}
relaxationFactors
{{
    equations {{ ".*" 0.9; ".*Final" 1; }}
}}
"""))


def probe_series(case):
    """(t, U) at PROBE from the probes function object's output."""
    path = case / "postProcessing" / "probes" / "0" / "U"
    t, u = [], []
    for line in path.read_text().splitlines():
        m = re.match(r"\s*([0-9.eE+-]+)\s+\(([^)]*)\)", line)
        if m:
            t.append(float(m.group(1)))
            u.append([float(c) for c in m.group(2).split()])
    return np.array(t), np.array(u)


def shedding(t, uy):
    """Period (s) and amplitude (standard deviation, m/s) of the lateral velocity at the probe
    over the samples given: the mean interval between upward crossings of its mean, linearly
    interpolated. Period None with fewer than three crossings."""
    d = uy - uy.mean()
    up = np.nonzero((d[:-1] < 0.0) & (d[1:] >= 0.0))[0]
    crossings = t[up] + (t[up + 1] - t[up]) * (-d[up]) / (d[up + 1] - d[up])
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1) if len(crossings) >= 3 else None
    return period, float(d.std()), len(crossings)


def time_dirs(case):
    """The case's time folders by time, 0 excluded."""
    out = {}
    for d in case.iterdir():
        if re.fullmatch(r"\d+(\.\d+)?(e[+-]?\d+)?", d.name) and float(d.name) > 0:
            out[float(d.name)] = d
    return dict(sorted(out.items()))


def pimple_log(case):
    """(time steps, mean and last deltaT, largest Courant number of the last step) from
    log.pimpleFoam."""
    text = (case / "log.pimpleFoam").read_text()
    dts = [float(v) for v in re.findall(r"^deltaT = ([0-9.eE+-]+)$", text, re.M)]
    cos = re.findall(r"^Courant Number mean: [0-9.eE+-]+ max: ([0-9.eE+-]+)$", text, re.M)
    return len(dts), (float(np.mean(dts)) if dts else None), (dts[-1] if dts else None), \
        (float(cos[-1]) if cos else None)


def run_steady(case, n_h, max_iterations, full=False):
    """Writes and runs the steady case (blockMesh, simpleFoam, the cell centres) in `case`.
    Returns the latest time's cell centres and U, and the solver log's (iterations,
    converged, residuals)."""
    write_case(case, n_h, max_iterations, full=full)
    run(case, "blockMesh")
    run(case, "simpleFoam")
    run(case, "postProcess", "-func", "writeCellCentres", "-latestTime")
    latest = max((d for d in case.iterdir() if re.fullmatch(r"\d+", d.name) and d.name != "0"),
                 key=lambda d: int(d.name))
    return read_vector_field(latest / "C"), read_vector_field(latest / "U"), solver_log(case)


def run_unsteady(args, case, start):
    """--unsteady: the steady solution on the full domain, then pimpleFoam from it, averaging
    U over the window [spin-up, spin-up + window]. Returns the JSON result."""
    centres, steady_u, (iterations, converged, residuals) = run_steady(
        case, args.cells_per_h, args.max_iterations, full=True)
    steady_s = time.monotonic() - start
    t_end = args.spin_up + args.window
    prepare_transient(case, args.model, t_end, args.spin_up, args.window, args.max_co,
                      args.outer_correctors, args.cells_per_h)
    run(case, "pimpleFoam")
    wall_s = time.monotonic() - start

    times = time_dirs(case)
    t_last = max(times)
    if abs(t_last - t_end) > 1e-6 * t_end or not (times[t_last] / "UMean").exists():
        raise SystemExit(f"pimpleFoam ended at {t_last} s without UMean, not at {t_end} s")
    u_mean = read_vector_field(times[t_last] / "UMean")
    # The mean over the window's first half is UMean written at its middle (fieldAverage
    # weights by the time step); the second half's follows from the whole window's.
    mids = [t for t in times if args.spin_up < t < t_last and (times[t] / "UMean").exists()]
    halves = None
    if mids:
        t_mid = min(mids, key=lambda t: abs(t - (args.spin_up + 0.5 * args.window)))
        first = read_vector_field(times[t_mid] / "UMean")
        second = (u_mean * (t_last - args.spin_up) - first * (t_mid - args.spin_up)) / (t_last - t_mid)
        halves = {"split_s": t_mid,
                  "first_half_H": reattachment_length(centres, first),
                  "second_half_H": reattachment_length(centres, second)}
    t, u = probe_series(case)
    averaged = t >= args.spin_up
    period, amplitude, crossings = shedding(t[averaged], u[averaged, 1])
    steps, dt_mean, dt_last, co_last = pimple_log(case)
    return {
        "reattachment_H": reattachment_length(centres, u_mean),
        "reattachment_mirror_H": reattachment_length(centres, u_mean, side=-1.0),
        "halves": halves,
        "steady_reattachment_H": reattachment_length(centres, steady_u),
        "cells": len(centres),
        "cells_per_h": args.cells_per_h,
        "iterations": iterations,
        "converged": converged,
        "residuals": residuals,
        "residual_targets": RESIDUAL_TARGETS,
        "unsteady": True,
        "model": args.model,
        "window_s": [args.spin_up, t_last],
        "time_steps": steps,
        "max_co": args.max_co,
        "outer_correctors": args.outer_correctors,
        "delta_t_mean_s": dt_mean,
        "delta_t_last_s": dt_last,
        "courant_last": co_last,
        "probe": list(PROBE),
        "shedding_period_s": period,
        "strouhal": (H / (period * U_BULK)) if period else None,
        "probe_uy_std": amplitude,
        "probe_uy_crossings": crossings,
        "steady_wall_s": round(steady_s, 1),
        "wall_s": round(wall_s, 1),
        "openfoam": openfoam_version(case),
    }


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
    centres, velocity, (iterations, converged, residuals) = run_steady(
        case, args.cells_per_h, args.max_iterations)
    wall_s = time.monotonic() - start
    result = {
        "reattachment_H": reattachment_length(centres, velocity),
        "cells": len(centres),
        "cells_per_h": args.cells_per_h,
        "iterations": iterations,
        "converged": converged,
        "residuals": residuals,
        "residual_targets": RESIDUAL_TARGETS,
        "wall_s": round(wall_s, 1),
        "openfoam": openfoam_version(case),
    }
    print(json.dumps(result))
    if result["reattachment_H"] is None:
        sys.exit("no reversed flow behind the cube")


if __name__ == "__main__":
    main()
