#!/usr/bin/env bash
# The source coverage a fuzz corpus reaches: each target's corpus (a folder per target, as
# `SADESIM_FUZZ_CORPUS` of tests/fuzz.sh keeps them) is run once through a build of the
# target instrumented for source coverage (`cargo fuzz coverage`), and llvm-cov reports the
# lines covered in the files the target is there to test (the list below). Not part of
# tests/run.sh: it measures a long run's corpus (fuzz/README.md "Coverage").
#
#   bash tests/fuzz-coverage.sh /var/cache/sadesim-fuzz/corpus [target ...]
#
# Needs llvm-profdata and llvm-cov of the compiler's LLVM major version (rustc -vV): the
# rustup component llvm-tools cannot be installed here, Debian's llvm-<major> can
# (installed when missing). The coverage build goes to fuzz/target (cargo fuzz coverage does
# not follow CARGO_TARGET_DIR); the reports to fuzz/coverage/<target>/.
set -euo pipefail
cd "$(dirname "$0")/.."

corpus_root=${1:?usage: tests/fuzz-coverage.sh CORPUS_ROOT [target ...]}
shift
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(pbf dem bundle mavlink_frame mavlink_session mavlink_router scenario shard_wire orbits openfoam)

# The files each target exists to test (regular expressions on the path), whatever else its
# inputs reach: the reader, decoder or state machine, not the libraries under it.
declare -A under_test=(
  [pbf]='world/src/(osm\.rs|osm/(pbf|assemble|parts)\.rs|protobuf\.rs)'
  [dem]='world/src/dem(\.rs|/tiff\.rs)'
  [bundle]='world/src/(bundle|index)\.rs'
  [mavlink_frame]='engine/src/mavlink/(frame|signing)\.rs'
  [mavlink_session]='engine/src/mavlink/(session\.rs|session/|params\.rs|params/|mission_protocol/|streams\.rs|px4_mode\.rs)'
  [mavlink_router]='engine/src/mavlink/(frame|signing)\.rs'
  [scenario]='crds/src/(validate\.rs|validate/|document\.rs|criteria\.rs|zones\.rs|fleet\.rs|polygon\.rs|geo\.rs|plan\.rs)|planner/src/lib\.rs'
  [shard_wire]='sim-worker/src/transport/wire\.rs'
  [orbits]='gnss/src/(orbits|omm)\.rs'
  [openfoam]='wind/src/(openfoam|foam_import)\.rs'
)

major=$(rustc -vV | sed -n 's/^LLVM version: \([0-9]*\).*/\1/p')
llvm=/usr/lib/llvm-$major/bin
if [ ! -x "$llvm/llvm-cov" ]; then
  echo "--> installing Debian's llvm-$major (llvm-profdata and llvm-cov of rustc's LLVM)"
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q "llvm-$major" >/dev/null
fi
triple=$(rustc -vV | sed -n 's/^host: //p')
# A copy of each corpus is measured: a fuzzer still running on it removes inputs it reduced.
snapshot=$(mktemp -d)
trap 'rm -rf "$snapshot"' EXIT
mkdir -p fuzz/coverage

for target in "${targets[@]}"; do
  pattern=${under_test[$target]:?"no files under test listed for $target"}
  [ -d "$corpus_root/$target" ] || { echo "$corpus_root/$target: no corpus of $target (a folder of inputs)" >&2; exit 1; }
  cp -r "$corpus_root/$target" "$snapshot/$target" 2>/dev/null || true # (inputs removed meanwhile)
  inputs=$(find "$snapshot/$target" -type f | wc -l)
  # cargo fuzz coverage merges the raw profiles it finds there: each measurement starts clean.
  rm -rf "fuzz/coverage/$target"
  (cd fuzz && cargo fuzz coverage --sanitizer none --llvm-path "$llvm" "$target" "$snapshot/$target") \
    >"fuzz/coverage/$target.log" 2>&1 || { tail -c 3000 "fuzz/coverage/$target.log"; exit 1; }
  binary=fuzz/target/$triple/coverage/$triple/release/$target
  profile=fuzz/coverage/$target/coverage.profdata
  report=fuzz/coverage/$target/report.txt
  "$llvm/llvm-cov" report "$binary" -instr-profile="$profile" >"$report"
  # Filename Regions Missed Cover Functions Missed Executed Lines Missed Cover ...
  # llvm-cov names the files without the leading "/" of their common root.
  awk -v target="$target" -v inputs="$inputs" -v repo="${PWD#/}/" -v pattern="^($pattern)" '
    index($1, repo) == 1 { $1 = substr($1, length(repo) + 1) }
    $1 ~ pattern && $8 > 0 { files++; lines += $8; missed += $9; detail = detail sprintf("  %-60s %5d lines, %6.2f%%\n", $1, $8, 100 * ($8 - $9) / $8) }
    END {
      if (files == 0) { print target ": no file under test in the report" > "/dev/stderr"; exit 1 }
      printf "%s (%d inputs): %d of %d lines covered (%.1f%%) in %d files under test\n%s", target, inputs, lines - missed, lines, 100 * (lines - missed) / lines, files, detail
    }' "$report"
  rm -f "fuzz/coverage/$target.log"
done
