"""The steady case of the surface-mounted cube (tests/cfd/openfoam_cube.py): the channel
and the cube, the graded block mesh, the inlet profiles, the case files, running OpenFOAM
and reading its fields and logs, the reattachment length."""
import math
import os
import re
import subprocess

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


def solution_fields(centres, cells_per_h, log):
    """The result's fields on the mesh and the steady solver: cells, iterations, whether
    the residual targets were met, the final residuals and the targets."""
    iterations, converged, residuals = log
    return {
        "cells": len(centres),
        "cells_per_h": cells_per_h,
        "iterations": iterations,
        "converged": converged,
        "residuals": residuals,
        "residual_targets": RESIDUAL_TARGETS,
    }
