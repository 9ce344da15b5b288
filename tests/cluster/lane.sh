#!/usr/bin/env bash
# The real-cluster lane of the test suite (tests/run.sh runs it): builds the cluster's
# binaries (cached outside the clone) and the project's images (tests/cluster/images.sh);
# runs the end-to-end scripts, each on a cluster of its own (tests/e2e/run.sh local: the
# chart, the quickstart to Succeeded with its archive verified in the object store, the early
# pilot exit, the live view; tests/e2e/teams.sh local: two teams sharing Kueue's quota); then
# brings a fresh cluster up, runs the tests of this folder against
# it (pytest), and tears everything down, also when a test fails.
#
#   bash tests/cluster/lane.sh            # KEEP_CLUSTER=1 keeps the second cluster up afterwards
#   bash tests/cluster/lane.sh -k helm    # pytest arguments: a part of this folder's tests
#
# Needs root, and what tests/install-tools.sh installs; the workspace's debug build
# (cargo build --workspace) for the images and the operator.
set -euo pipefail
cd "$(dirname "$0")/../.."

bin=$(tests/cluster/build.sh)
# A cluster left by an interrupted run goes first.
tests/cluster/down.sh
E2E_IMAGE_DIR=$(mktemp -d)
export E2E_IMAGE_DIR
CLUSTER_MEASUREMENTS=$E2E_IMAGE_DIR/measurements.jsonl
cleanup() {
  status=$?
  rm -rf "$E2E_IMAGE_DIR"
  if [ "${KEEP_CLUSTER:-0}" = 1 ]; then
    echo "cluster: kept (KEEP_CLUSTER=1); tests/cluster/down.sh removes it" >&2
  else
    tests/cluster/down.sh || status=1
  fi
  exit "$status"
}
trap cleanup EXIT

# The project's images, once for both clusters (tagged e2e, as tests/e2e/run.sh names them).
images_start=$SECONDS
tests/cluster/images.sh product e2e "$E2E_IMAGE_DIR"

# Each stage's wall time, said at its end (docs/kubernetes.md quotes them).
took() { echo "cluster: $1 took $((SECONDS - $2)) s" >&2; }
took "images.sh product" "$images_start"

if [ "${SADESIM_CLUSTER_E2E:-1}" = 1 ]; then
  stage=$SECONDS
  KEEP_CLUSTER=0 bash tests/e2e/run.sh local
  took "tests/e2e/run.sh local" "$stage"
  stage=$SECONDS
  KEEP_CLUSTER=0 bash tests/e2e/teams.sh local
  took "tests/e2e/teams.sh local" "$stage"
fi

stage=$SECONDS
kubeconfig=$(tests/cluster/up.sh)
tests/cluster/images.sh import "$E2E_IMAGE_DIR"
SADESIM_CLUSTER_MEASUREMENTS=${SADESIM_CLUSTER_MEASUREMENTS:-$CLUSTER_MEASUREMENTS} \
  SADESIM_CLUSTER_BIN=$bin SADESIM_CLUSTER_KUBECONFIG=$kubeconfig SADESIM_CLUSTER_IMAGE_TAG=e2e \
  .venv/bin/python -m pytest -q -p no:cacheprovider tests/cluster "$@"
took "the cluster tests (up, import, pytest)" "$stage"
took "the whole lane" 0
echo "cluster: bring-up $(cat "${SADESIM_CLUSTER_DIR:-/var/lib/sadesim-cluster}/up-seconds" 2>/dev/null || echo '?') s; measured (tests/cluster/test_cost.py):" >&2
cat "${SADESIM_CLUSTER_MEASUREMENTS:-$CLUSTER_MEASUREMENTS}" >&2 2>/dev/null || true
