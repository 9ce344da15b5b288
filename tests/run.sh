#!/usr/bin/env bash
# The whole test suite: the README's test command, and what CI runs (.ci/run).
# Installs missing tools first (tests/install-tools.sh), then: formatting, lints, Rust
# tests (cargo nextest), Python interop tests (pytest), bounded fuzzing of the file readers
# (tests/fuzz.sh), Helm chart lint and template, and the real-cluster lane (tests/cluster/lane.sh:
# Kubernetes built from upstream source, brought up on this machine, tested, torn down).
set -euo pipefail
cd "$(dirname "$0")/.."

# No incremental compilation cache unless asked: CI builds a fresh clone once, where the
# cache speeds nothing up and was 40 % of a 19 GB target directory (CI ran out of disk).
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"

bash tests/install-tools.sh

echo "==> cargo fmt --check"
cargo fmt --all -- --check

echo "==> cargo clippy"
cargo clippy --workspace --all-targets --locked -- -D warnings

echo "==> cargo build (binaries used by the interop tests)"
cargo build --workspace --locked

echo "==> helm lint / template"
.tools/bin/helm lint --strict charts/sadesim
.tools/bin/helm template sadesim charts/sadesim --include-crds \
  | .venv/bin/kubernetes-validate --strict --quiet -k 1.33.0 -
.tools/bin/helm template sadesim charts/sadesim --set console.enabled=true \
  | .venv/bin/kubernetes-validate --strict --quiet -k 1.33.0 -

echo "==> Python interop tests"
# The OpenFOAM reference cube (about 5 minutes of one core, no build needed) runs beside
# the others, which leave a core idle while they wait on pilots, browsers and clocks.
cube_log="$(mktemp)"
.venv/bin/python -m pytest -q -p no:cacheprovider tests/interop/test_openfoam_cube.py >"$cube_log" 2>&1 &
cube_pid=$!
# The short soak (tests/soak/soak.py, docs/performance.md "Soak"): 3 real-time minutes of
# 8 scripted drones with a ground station, failing if memory, file descriptors or threads
# grow. It needs little CPU, so it runs beside the interop tests too, in a network namespace
# of its own (its MAVLink and API ports are the defaults the interop tests use).
soak_dir="$(mktemp -d)"
unshare --net -- sh -c 'ip link set lo up && exec "$@"' soak \
  .venv/bin/python tests/soak/soak.py --sadesim target/debug/sadesim --minutes 3 --drones 8 \
  --interval 2 --out "$soak_dir" >"$soak_dir/soak.log" 2>&1 &
soak_pid=$!
trap 'kill "$cube_pid" "$soak_pid" 2>/dev/null || true' EXIT
.venv/bin/python -m pytest -q tests/interop --ignore=tests/interop/test_openfoam_cube.py
echo "==> Python interop tests: the OpenFOAM reference cube (tests/interop/test_openfoam_cube.py)"
cube_status=0
wait "$cube_pid" || cube_status=$?
cat "$cube_log"
rm -f "$cube_log"
[ "$cube_status" -eq 0 ] || { echo "the OpenFOAM reference cube failed (exit $cube_status)"; exit 1; }
echo "==> the short soak (tests/soak/soak.py)"
soak_status=0
wait "$soak_pid" || soak_status=$?
cat "$soak_dir/soak.log"
rm -rf "$soak_dir"
trap - EXIT
[ "$soak_status" -eq 0 ] || { echo "the short soak failed (exit $soak_status)"; exit 1; }

echo "==> the real-cluster lane (tests/cluster/lane.sh)"
bash tests/cluster/lane.sh

echo "==> fuzzing (tests/fuzz.sh: cargo-fuzz, ${SADESIM_FUZZ_SECONDS:-25} s per target)"
bash tests/fuzz.sh

echo "==> Rust tests"
cargo nextest run --workspace --locked --no-fail-fast
