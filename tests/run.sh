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

echo "==> Python interop tests"
.venv/bin/python -m pytest -q tests/interop

echo "==> the real-cluster lane (tests/cluster/lane.sh)"
bash tests/cluster/lane.sh

echo "==> fuzzing the file readers (cargo-fuzz, ${SADESIM_FUZZ_SECONDS:-60} s per target)"
bash tests/fuzz.sh

echo "==> Rust tests"
cargo nextest run --workspace --locked --no-fail-fast
