#!/usr/bin/env bash
# End-to-end test on a local cluster: create a k3d or kind cluster, build and import the
# images, start MinIO as the archive, install the chart, apply the quickstart run, wait for
# Succeeded, and verify the archived run against its manifest; then a run whose pilot Job
# exits after 30 s must end there (tests/e2e/pilot-exit.yaml); a run with the live view streams
# frames through its renderer Service, serves its drones' onboard camera frames from the
# coordinator (rendered on lavapipe in the camera image), and takes the renderer with it when
# deleted (tests/e2e/view.yaml).
#
#   tests/e2e/run.sh k3d     # or: tests/e2e/run.sh kind
#   tests/e2e/run.sh local   # the cluster of tests/cluster/, built here from upstream source
#
# Needs: docker (a running engine), kubectl, curl, k3d or kind, and helm (.tools/bin/helm from
# tests/install-tools.sh, or on PATH); local needs what tests/install-tools.sh installs and
# root instead. KEEP_CLUSTER=1 keeps the cluster afterwards. tests/cluster/lane.sh (part of
# tests/run.sh) runs it with local; on local the archive is Versity's S3 gateway instead of
# MinIO.
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=tests/e2e/lib.sh
. tests/e2e/lib.sh

TOOL=${1:-}
case "$TOOL" in
  k3d | kind | local) ;;
  *) echo "usage: $0 k3d|kind|local" >&2; exit 2 ;;
esac

CLUSTER=${CLUSTER:-sadesim-e2e}
TAG=${TAG:-e2e}
OPERATOR_IMAGE=ghcr.io/sadesim/sadesim:$TAG
WORKER_IMAGE=ghcr.io/sadesim/sim-worker:$TAG
CAMERA_IMAGE=ghcr.io/sadesim/sim-worker-camera:$TAG
# The pilot images under the names the examples give (spec.pilot.image), so the examples
# apply unchanged.
PILOT_EXAMPLES_IMAGE=ghcr.io/sadesim/pilot-examples:0.1.0
SYSTEM_NS=sadesim-system
RUN_NS=default
RUN=quickstart
BUCKET=sadesim-runs
# Throwaway credentials of the throwaway MinIO.
MINIO_USER=sadesim
MINIO_PASSWORD=sadesim-e2e-secret
TIMEOUT=${TIMEOUT:-900}

e2e_require_tools e2e "$TOOL"
HELM=$(e2e_helm)

cleanup() {
  status=$?
  if [ "$status" -ne 0 ]; then
    echo "e2e: FAILED; state of the cluster:" >&2
    kubectl get simrun,jobs,pods,svc -n "$RUN_NS" -o wide >&2 || true
    kubectl describe simrun -n "$RUN_NS" >&2 || true
    kubectl logs -n "$SYSTEM_NS" deployment/sadesim --tail=100 >&2 || true
    kubectl logs -n "$RUN_NS" "$RUN-coordinator" --tail=50 >&2 || true
  fi
  if [ -n "${FORWARD_PID:-}" ]; then kill "$FORWARD_PID" 2>/dev/null || true; fi
  if [ "${KEEP_CLUSTER:-0}" != 1 ]; then
    step "deleting cluster $CLUSTER (KEEP_CLUSTER=1 keeps it)"
    e2e_delete_cluster "$TOOL" "$CLUSTER"
  fi
  exit "$status"
}
trap cleanup EXIT

step "creating $TOOL cluster $CLUSTER"
e2e_create_cluster "$TOOL" "$CLUSTER"

step "building images"
e2e_build_images "$TOOL" "$TAG"

step "importing images into the cluster"
e2e_import_images "$TOOL" "$CLUSTER" "$OPERATOR_IMAGE" "$WORKER_IMAGE" "$CAMERA_IMAGE" "$PILOT_EXAMPLES_IMAGE"

step "starting the object store (the archive) with bucket $BUCKET"
ENDPOINT=$(e2e_start_object_store "$TOOL" "$MINIO_USER" "$MINIO_PASSWORD" "$BUCKET")

step "installing the chart"
e2e_install_chart "$HELM" "$SYSTEM_NS" "$TAG" "$BUCKET" "$MINIO_USER" "$MINIO_PASSWORD" "$RUN_NS" "$ENDPOINT"
kubectl get crd simulationruns.sadesim.io

# Waits for run $1 to reach Succeeded (fails early on Failed/Aborted, with its message).
wait_succeeded() {
  local run=$1 deadline=$((SECONDS + TIMEOUT)) phase sim
  while :; do
    phase=$(kubectl get simrun "$run" -n "$RUN_NS" -o jsonpath='{.status.phase}' 2>/dev/null || true)
    sim=$(kubectl get simrun "$run" -n "$RUN_NS" -o jsonpath='{.status.simTimeS}' 2>/dev/null || true)
    echo "  $run: phase=${phase:-<none>} simTimeS=${sim:-<none>}"
    case "$phase" in
      Succeeded) return 0 ;;
      Failed | Aborted)
        echo "e2e: $run ended $phase: $(kubectl get simrun "$run" -n "$RUN_NS" -o jsonpath='{.status.message}')" >&2
        exit 1 ;;
    esac
    [ "$SECONDS" -lt "$deadline" ] || { echo "e2e: $run timed out in phase ${phase:-<none>}" >&2; exit 1; }
    sleep 5
  done
}

step "applying examples/quickstart.yaml"
kubectl delete simrun "$RUN" -n "$RUN_NS" --ignore-not-found --wait
kubectl apply -n "$RUN_NS" -f examples/quickstart.yaml

step "waiting up to ${TIMEOUT}s for Succeeded"
wait_succeeded "$RUN"

step "checking the archive"
url=$(kubectl get simrun "$RUN" -n "$RUN_NS" -o jsonpath='{.status.archive.url}')
uid=$(kubectl get simrun "$RUN" -n "$RUN_NS" -o jsonpath='{.metadata.uid}')
case "$url" in
  "s3://$BUCKET/$RUN_NS/$RUN/$uid"*) echo "  status.archive.url=$url" ;;
  *) echo "e2e: status.archive.url is '$url', expected s3://$BUCKET/$RUN_NS/$RUN/$uid/" >&2; exit 1 ;;
esac
# `sadesim archive verify` (in the worker image: the operator image has only the controller)
# re-reads every file against manifest.json; it runs in the
# cluster (with the run's object-store Secret) so MinIO need not be reachable from here.
kubectl delete pod -n "$RUN_NS" archive-verify --ignore-not-found --wait
kubectl apply -n "$RUN_NS" -f - <<YAML
apiVersion: v1
kind: Pod
metadata: {name: archive-verify}
spec:
  restartPolicy: Never
  securityContext: {runAsNonRoot: true, runAsUser: 65532, seccompProfile: {type: RuntimeDefault}}
  containers:
    - name: verify
      image: $WORKER_IMAGE
      command: [/usr/local/bin/sadesim]
      args: [archive, verify, --quiet, "$url"]
      envFrom: [{secretRef: {name: sadesim-object-store}}]
      securityContext: {allowPrivilegeEscalation: false, readOnlyRootFilesystem: true, capabilities: {drop: [ALL]}}
YAML
kubectl wait -n "$RUN_NS" pod/archive-verify --for=jsonpath='{.status.phase}'=Succeeded --timeout=180s || {
  kubectl logs -n "$RUN_NS" archive-verify >&2 || true
  echo "e2e: archive verify failed" >&2
  exit 1
}
kubectl logs -n "$RUN_NS" archive-verify
verdict=$(kubectl get simrun "$RUN" -n "$RUN_NS" -o jsonpath='{.status.verdict.passed}')
[ "$verdict" = true ] || { echo "e2e: verdict.passed is '$verdict'" >&2; exit 1; }

# A piloted example as a user applies it: the pymavlink quickstart's pilot runs from the
# example pilots' image, flies the four drones through the run's router and Services,
# and ends the run when it exits.
PILOTED_RUN=quickstart-pymavlink
step "applying examples/$PILOTED_RUN.yaml (its pilot from $PILOT_EXAMPLES_IMAGE)"
kubectl delete simrun "$PILOTED_RUN" -n "$RUN_NS" --ignore-not-found --wait
kubectl apply -n "$RUN_NS" -f "examples/$PILOTED_RUN.yaml"
wait_succeeded "$PILOTED_RUN"
kubectl logs -n "$RUN_NS" "job/$PILOTED_RUN-pilot" --tail=5 || true
verdict=$(kubectl get simrun "$PILOTED_RUN" -n "$RUN_NS" -o jsonpath='{.status.verdict.passed}')
[ "$verdict" = true ] || { echo "e2e: $PILOTED_RUN verdict.passed is '$verdict'" >&2; exit 1; }

# A pilot Job that exits ends its run (onExit: endRun): the operator annotates the
# coordinator Pod sadesim.io/stop=pilotExited and the coordinator ends the run, in real
# time, about 30 s in instead of at its 10-minute duration.
PILOT_RUN=pilot-exit
step "applying tests/e2e/pilot-exit.yaml (a pilot that exits after 30 s)"
kubectl delete simrun "$PILOT_RUN" -n "$RUN_NS" --ignore-not-found --wait
kubectl apply -n "$RUN_NS" -f tests/e2e/pilot-exit.yaml
wait_succeeded "$PILOT_RUN"
ended=$(kubectl get simrun "$PILOT_RUN" -n "$RUN_NS" -o jsonpath='{.status.conditions[?(@.type=="Running")].message}')
sim=$(kubectl get simrun "$PILOT_RUN" -n "$RUN_NS" -o jsonpath='{.status.simTimeS}')
case "$ended" in
  *"(pilotExited)"*) echo "  $PILOT_RUN: $ended at simTimeS=$sim" ;;
  *) echo "e2e: $PILOT_RUN did not end by its pilot: Running condition '$ended'" >&2; exit 1 ;;
esac
awk -v s="$sim" 'BEGIN { exit !(s < 300) }' || { echo "e2e: $PILOT_RUN ran to simTimeS=$sim, not ~30 s" >&2; exit 1; }

# The live view: the renderer Deployment follows the coordinator's stream and serves it;
# deleting the run deletes the renderer (owner references).
VIEW_RUN=live-view
step "applying tests/e2e/view.yaml (rendering.enabled)"
kubectl delete simrun "$VIEW_RUN" -n "$RUN_NS" --ignore-not-found --wait
kubectl apply -n "$RUN_NS" -f tests/e2e/view.yaml
deadline=$((SECONDS + TIMEOUT))
until [ "$(kubectl get simrun "$VIEW_RUN" -n "$RUN_NS" -o jsonpath='{.status.phase}' 2>/dev/null)" = Running ]; do
  [ "$SECONDS" -lt "$deadline" ] || { echo "e2e: $VIEW_RUN never reached Running" >&2; exit 1; }
  sleep 5
done
kubectl rollout status -n "$RUN_NS" "deployment/$VIEW_RUN-renderer" --timeout=300s
endpoint=$(kubectl get simrun "$VIEW_RUN" -n "$RUN_NS" -o jsonpath='{.status.endpoints.renderer}')
echo "  status.endpoints.renderer=$endpoint"
kubectl port-forward -n "$RUN_NS" "svc/$VIEW_RUN-renderer" 18490:8490 >/dev/null 2>&1 &
FORWARD_PID=$!
sleep 3
curl -fsS http://127.0.0.1:18490/scene.json | grep -q '"mode":"live"' || { echo "e2e: the renderer's scene.json is not a live scene" >&2; exit 1; }
frames=$(curl -sN --max-time 5 http://127.0.0.1:18490/live | grep -c '^event: frame' || true)
[ "$frames" -ge 10 ] || { echo "e2e: the renderer streamed $frames frames in 5 s, expected at least 10" >&2; exit 1; }
echo "  the renderer streamed $frames frames in 5 s"
kill "$FORWARD_PID" 2>/dev/null || true
# The onboard cameras: the coordinator renders them and serves them on its Service.
cameras=$(kubectl get simrun "$VIEW_RUN" -n "$RUN_NS" -o jsonpath='{.status.endpoints.cameras}')
[ "$cameras" = "http://$VIEW_RUN-airspace.$RUN_NS.svc:8490/cameras" ] \
  || { echo "e2e: status.endpoints.cameras is '$cameras'" >&2; exit 1; }
kubectl port-forward -n "$RUN_NS" "svc/$VIEW_RUN-airspace" 18491:8490 >/dev/null 2>&1 &
FORWARD_PID=$!
sleep 3
latest=$(curl -fsS http://127.0.0.1:18491/cameras | grep -o '"latest":"[^"]*"' | head -n 1 | cut -d'"' -f4)
[ -n "$latest" ] || { echo "e2e: the coordinator lists no camera at /cameras" >&2; exit 1; }
curl -fsS -o /tmp/sadesim-e2e-frame.jpg "http://127.0.0.1:18491$latest"
# A JPEG starts with FF D8 FF; 160x120 frames of a city are a few kB.
magic=$(head -c 3 /tmp/sadesim-e2e-frame.jpg | od -An -tx1 | tr -d ' \n')
[ "$magic" = ffd8ff ] || { echo "e2e: $latest is not a JPEG (starts with $magic)" >&2; exit 1; }
# The camera's size (tests/e2e/view.yaml: 160x120), from the JPEG's frame header. (A frame of
# a park seen from above can be one colour: its byte count says nothing.)
size=$(wc -c < /tmp/sadesim-e2e-frame.jpg)
dims=$(python3 - /tmp/sadesim-e2e-frame.jpg <<'PY'
import sys
data = open(sys.argv[1], "rb").read()
i = 2
while i + 9 < len(data):
    marker, length = data[i + 1], int.from_bytes(data[i + 2:i + 4], "big")
    if marker in (0xC0, 0xC1, 0xC2):
        print(f"{int.from_bytes(data[i + 7:i + 9], 'big')}x{int.from_bytes(data[i + 5:i + 7], 'big')}")
        break
    i += 2 + length
PY
)
[ "$dims" = 160x120 ] || { echo "e2e: $latest is $dims, expected the camera's 160x120" >&2; exit 1; }
kubectl logs -n "$RUN_NS" "$VIEW_RUN-coordinator" | grep -m1 'onboard cameras:' || true
echo "  the coordinator served $latest, a $dims JPEG of $size bytes"
kill "$FORWARD_PID" 2>/dev/null || true
kubectl delete simrun "$VIEW_RUN" -n "$RUN_NS" --wait
deadline=$((SECONDS + 120))
while kubectl get deployment -n "$RUN_NS" "$VIEW_RUN-renderer" >/dev/null 2>&1; do
  [ "$SECONDS" -lt "$deadline" ] || { echo "e2e: the renderer outlived its run" >&2; exit 1; }
  sleep 3
done

step "e2e passed ($TOOL): $RUN Succeeded, archive at $url verified; $PILOTED_RUN flown by its pilot image; $PILOT_RUN ended by its pilot at ${sim} s; the live view streamed $frames frames; a $dims camera frame"
