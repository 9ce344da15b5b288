#!/usr/bin/env bash
# Bounded coverage-guided fuzzing: the cargo-fuzz (libFuzzer) targets in fuzz/ for the
# world's file readers (OSM PBF, DEM, world bundle), MAVLink (frames and signing, the
# per-drone session, the router's datagram path), the scenario reader down to the plan, the
# shard protocol, orbit files and OpenFOAM fields (fuzz/README.md). Part of tests/run.sh.
#
# The seed corpora are written by the owning crates' `fuzz_seeds` tests from their own
# encoders and the repository's examples (nothing is committed); each target then fuzzes a
# fresh copy for SADESIM_FUZZ_SECONDS (default 25), SADESIM_FUZZ_JOBS targets at a time
# (default: one per core). SADESIM_FUZZ_TARGETS picks targets (space-separated names).
# SADESIM_FUZZ_CORPUS keeps the corpora across runs: each target fuzzes
# $SADESIM_FUZZ_CORPUS/<target>, the seeds are added to it and what libFuzzer finds stays, so
# runs of an hour add up (the long runs of fuzz/README.md use it). A crash (a panic, an error of
# more than one line, an input slower than 10 s, more than 2 GB of memory) fails the script;
# libFuzzer names the input it saved under fuzz/artifacts/<target>/, which replays with
# `cd fuzz && cargo fuzz run --sanitizer none <target> <file>`.
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${SADESIM_FUZZ_SECONDS:-25}"
jobs="${SADESIM_FUZZ_JOBS:-$(nproc)}"
read -r -a targets <<<"${SADESIM_FUZZ_TARGETS:-pbf dem bundle mavlink_frame mavlink_session mavlink_router scenario shard_wire orbits openfoam}"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The whole workspace's test binaries, as the nextest stage of tests/run.sh builds them (same
# packages and features, so that stage reuses them rather than building again).
echo "--> seed corpora (the fuzz_seeds tests of world, engine, gnss, wind, planner, sim-worker)"
SADESIM_FUZZ_SEEDS="$work/corpus" cargo nextest run --workspace --locked --no-tests=fail \
  --status-level fail --final-status-level fail fuzz_seeds
corpus="$work/corpus"
for target in "${targets[@]}"; do
  [ -n "$(ls -A "$work/corpus/$target" 2>/dev/null)" ] || { echo "no seeds for $target" >&2; exit 1; }
done
if [ -n "${SADESIM_FUZZ_CORPUS:-}" ]; then
  corpus=$SADESIM_FUZZ_CORPUS
  for target in "${targets[@]}"; do
    mkdir -p "$corpus/$target"
    cp -n "$work/corpus/$target"/* "$corpus/$target/"
    echo "corpus $corpus/$target: $(find "$corpus/$target" -type f | wc -l) inputs"
  done
fi

# --sanitizer none: AddressSanitizer needs -Zsanitizer (a nightly compiler); the readers are
# safe Rust (unsafe_code is forbidden), where what fuzzing finds is panics, overflows (debug
# assertions are on), hangs and runaway allocations: no sanitizer is needed to see those.
# The instrumented build goes to a cache outside the clone, keyed by the toolchain, so a
# fresh clone (CI) builds only the repository's own crates, not the third-party ones.
# SADESIM_FUZZ_CACHE sets its root (default /var/cache/sadesim-fuzz; fuzz/target when that
# cannot be written).
cache_root="${SADESIM_FUZZ_CACHE:-/var/cache/sadesim-fuzz}"
toolchain_key=$(rustc -vV | sha256sum | cut -c1-12)
if mkdir -p "$cache_root/$toolchain_key" 2>/dev/null && [ -w "$cache_root/$toolchain_key" ]; then
  export CARGO_TARGET_DIR="$cache_root/$toolchain_key/target"
fi
echo "--> cargo fuzz build (into ${CARGO_TARGET_DIR:-fuzz/target})"
build_start=$SECONDS
(cd fuzz && cargo fuzz build --sanitizer none)
echo "cargo fuzz build: $((SECONDS - build_start)) s"

fuzz() {
  local target=$1 rc=0
  (cd fuzz && cargo fuzz run --sanitizer none "$target" "$corpus/$target" -- \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1) \
    >"$work/$target.log" 2>&1 || rc=$?
  echo "$rc" >"$work/$target.rc"
}

echo "--> cargo fuzz run: ${targets[*]}, ${seconds} s each, ${jobs} at a time"
for target in "${targets[@]}"; do
  while (( $(jobs -rp | wc -l) >= jobs )); do wait -n || true; done
  fuzz "$target" &
done
wait
failed=()
for target in "${targets[@]}"; do
  if [ "$(cat "$work/$target.rc")" = 0 ]; then
    # "Done 1107947 runs in 61 second(s)", the final coverage and corpus size, and the
    # edges instrumented in the whole target ("Loaded 1 modules (N inline 8-bit counters)").
    done_line=$(grep -E '^Done [0-9]+ runs' "$work/$target.log" | tail -1)
    runs=$(awk '{print $2}' <<<"$done_line")
    secs=$(awk '{print $5}' <<<"$done_line")
    stats=$(grep -E '^#[0-9]+[[:space:]]+DONE' "$work/$target.log" | tail -1 | grep -oE '(cov|ft|corp): [0-9]+' | paste -sd' ')
    edges=$(grep -oE 'Loaded 1 modules +\([0-9]+ inline 8-bit counters' "$work/$target.log" | grep -oE '[0-9]+ inline' | head -1 | cut -d' ' -f1)
    echo "$target: $runs runs in $secs s ($(( runs / (secs > 0 ? secs : 1) )) per second), $stats, ${edges:-?} edges instrumented"
  else
    failed+=("$target")
    echo "$target: FAILED"
    tail -n 60 "$work/$target.log"
  fi
done
if (( ${#failed[@]} > 0 )); then
  echo "fuzzing found a crash in: ${failed[*]} (inputs under fuzz/artifacts/)" >&2
  exit 1
fi
