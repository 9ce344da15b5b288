"""Unsteady RANS of the surface-mounted cube (`tests/cfd/openfoam_cube.py --unsteady`):
pimpleFoam from the steady solution on the full domain, the averaged field, the shedding
probe and its period."""
import math
import re
import shutil
import time

import numpy as np

from cube_case import (C_MU, H, U_BULK, foam_file, inlet_profiles, openfoam_version,
                       read_vector_field, reattachment_length, run, run_steady, solution_fields)

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


def run_unsteady(args, case, start):
    """--unsteady: the steady solution on the full domain, then pimpleFoam from it, averaging
    U over the window [spin-up, spin-up + window]. Returns the JSON result."""
    centres, steady_u, log = run_steady(
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
        **solution_fields(centres, args.cells_per_h, log),
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
