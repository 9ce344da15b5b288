#!/usr/bin/env bash
# Kueue on the test cluster (tests/cluster/up.sh), for the two-team walkthrough
# (tests/e2e/teams.sh local): the manifests of Kueue's own kustomization (config/default in
# the sigs.k8s.io/kueue module, rendered by kubectl's built-in kustomize), with the image
# built here (images.sh base, imported by up.sh) instead of Kueue's registry's, never pulled.
#
#   tests/cluster/kueue.sh install     # applies them and waits for the manager and its APIs
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/cluster/lib.sh
. "$here/lib.sh"

[ "${1:-}" = install ] || { echo "usage: $0 install" >&2; exit 2; }

src=$(cd "$here/build" && GOFLAGS=-mod=mod go mod download -json "sigs.k8s.io/kueue@$KUEUE_VERSION" \
  | sed -n 's/^\s*"Dir": "\(.*\)",$/\1/p')
[ -d "$src/config/default" ] || { cluster_log "sigs.k8s.io/kueue@$KUEUE_VERSION has no config/default"; exit 1; }
manifests=$CLUSTER_DIR/kueue.yaml
kubectl kustomize "$src/config/default" \
  | sed -E "s#^( +image: ).*/kueue/kueue:.*#\1$KUEUE_IMAGE#; s#^( +imagePullPolicy: )Always#\1IfNotPresent#" >"$manifests"
grep -q "image: $KUEUE_IMAGE" "$manifests" || { cluster_log "Kueue's manifests name no kueue image to replace"; exit 1; }
kubectl apply --server-side -f "$manifests" >/dev/null
kubectl wait -n kueue-system --for=condition=Available deployment/kueue-controller-manager --timeout=300s >&2
# The queue position comes from Kueue's visibility API (an aggregated API of Kueue's).
kubectl wait --for=condition=Available apiservice/v1beta2.visibility.kueue.x-k8s.io --timeout=120s >&2
cluster_log "Kueue $KUEUE_VERSION installed"
