#!/usr/bin/env bash
# End-to-end walkthrough of two teams sharing a cluster through Kueue (docs/kubernetes.md,
# "Teams sharing a cluster"): create a k3d or kind cluster, build and import the images,
# install Kueue (pinned), MinIO as the archive and the chart with its Kueue integration on;
# create two team namespaces with ResourceQuotas, a cohort of two ClusterQueues and a
# LocalQueue each (tests/e2e/cluster/kueue-teams.yaml); apply team A's run, then team B's while A's runs.
# Checks: each run is one Kueue Workload; B's run waits as a whole (Queued, no pod of it
# exists, its Workload pending with its reason) until A's run ends, then is admitted and
# succeeds; both runs are archived.
#
#   tests/e2e/teams.sh k3d     # or: tests/e2e/teams.sh kind
#   tests/e2e/teams.sh local   # the cluster of tests/cluster/, built here from upstream source
#
# Needs: docker (a running engine), kubectl, k3d or kind, and helm (.tools/bin/helm from
# tests/install-tools.sh, or on PATH); network access to Kueue's release; local needs root and
# what tests/install-tools.sh installs instead, and takes Kueue from its Go module
# (tests/cluster/kueue.sh). KEEP_CLUSTER=1 keeps the cluster afterwards. tests/cluster/lane.sh
# (part of tests/run.sh) runs it with local.
set -euo pipefail
cd "$(dirname "$0")/../.."
# shellcheck source=tests/e2e/lib.sh
. tests/e2e/lib.sh

TOOL=${1:-}
case "$TOOL" in
  k3d | kind | local) ;;
  *) echo "usage: $0 k3d|kind|local" >&2; exit 2 ;;
esac

CLUSTER=${CLUSTER:-sadesim-teams}
TAG=${TAG:-e2e}
KUEUE_VERSION=v0.19.4
OPERATOR_IMAGE=ghcr.io/sadesim/sadesim:$TAG
WORKER_IMAGE=ghcr.io/sadesim/sim-worker:$TAG
SYSTEM_NS=sadesim-system
BUCKET=sadesim-runs
MINIO_USER=sadesim
MINIO_PASSWORD=sadesim-e2e-secret
TIMEOUT=${TIMEOUT:-900}

e2e_require_tools teams "$TOOL"
HELM=$(e2e_helm)

cleanup() {
  status=$?
  if [ "$status" -ne 0 ]; then
    echo "teams: FAILED; state of the cluster:" >&2
    kubectl get simrun,workloads,pods -n team-a -o wide >&2 || true
    kubectl get simrun,workloads,pods -n team-b -o wide >&2 || true
    kubectl get clusterqueues -o wide >&2 || true
    kubectl logs -n "$SYSTEM_NS" deployment/sadesim --tail=100 >&2 || true
  fi
  if [ "${KEEP_CLUSTER:-0}" != 1 ]; then
    step "deleting cluster $CLUSTER (KEEP_CLUSTER=1 keeps it)"
    e2e_delete_cluster "$TOOL" "$CLUSTER"
  fi
  exit "$status"
}
trap cleanup EXIT

# field NS RUN JSONPATH: one field of a run ('' when absent).
field() { kubectl get simrun "$2" -n "$1" -o jsonpath="$3" 2>/dev/null || true; }

# wait_phase NS RUN PHASE: until the run is in PHASE (fails on Failed/Aborted).
wait_phase() {
  local ns=$1 run=$2 want=$3 deadline=$((SECONDS + TIMEOUT)) phase
  while :; do
    phase=$(field "$ns" "$run" '{.status.phase}')
    echo "  $ns/$run: phase=${phase:-<none>} kueue=$(field "$ns" "$run" '{.status.kueue.state}')"
    [ "$phase" = "$want" ] && return 0
    case "$phase" in
      Failed | Aborted) echo "teams: $ns/$run ended $phase: $(field "$ns" "$run" '{.status.message}')" >&2; exit 1 ;;
    esac
    [ "$SECONDS" -lt "$deadline" ] || { echo "teams: $ns/$run never reached $want" >&2; exit 1; }
    sleep 5
  done
}

step "creating $TOOL cluster $CLUSTER"
e2e_create_cluster "$TOOL" "$CLUSTER"

step "building and importing images"
e2e_build_images "$TOOL" "$TAG"
e2e_import_images "$TOOL" "$CLUSTER" "$OPERATOR_IMAGE" "$WORKER_IMAGE"

if [ "$TOOL" = local ]; then
  step "installing Kueue from its Go module (tests/cluster/kueue.sh)"
  tests/cluster/kueue.sh install
else
  step "installing Kueue $KUEUE_VERSION"
  kubectl apply --server-side -f "https://github.com/kubernetes-sigs/kueue/releases/download/$KUEUE_VERSION/manifests.yaml"
  kubectl wait -n kueue-system --for=condition=Available deployment/kueue-controller-manager --timeout=300s
  # The queue position comes from Kueue's visibility API (an aggregated API of Kueue's).
  kubectl wait --for=condition=Available apiservice/v1beta2.visibility.kueue.x-k8s.io --timeout=120s
fi

step "starting the object store (the archive)"
ENDPOINT=$(e2e_start_object_store "$TOOL" "$MINIO_USER" "$MINIO_PASSWORD" "$BUCKET")

step "the teams' namespaces, quotas and queues (tests/e2e/cluster/kueue-teams.yaml)"
# Kueue's webhooks answer only once its controller is up: retry the first apply.
for attempt in 1 2 3 4 5 6; do
  kubectl apply --server-side -f tests/e2e/cluster/kueue-teams.yaml && break
  [ "$attempt" -lt 6 ] || { echo "teams: Kueue refused tests/e2e/cluster/kueue-teams.yaml" >&2; exit 1; }
  sleep 10
done
kubectl wait --for=condition=Active clusterqueue/team-a clusterqueue/team-b --timeout=120s

step "installing the chart with the Kueue integration"
e2e_install_chart "$HELM" "$SYSTEM_NS" "$TAG" "$BUCKET" "$MINIO_USER" "$MINIO_PASSWORD" "team-a,team-b" "$ENDPOINT" \
  --set kueue.enabled=true

step "team A applies its run"
kubectl apply -f tests/e2e/team-a.yaml
wait_phase team-a survey-a Running
kubectl get workload -n team-a survey-a -o wide
[ "$(field team-a survey-a '{.status.kueue.state}')" = Admitted ] || { echo "teams: survey-a runs without an admitted Workload" >&2; exit 1; }

step "team B applies its run while A's runs: it must wait as a whole"
kubectl apply -f tests/e2e/team-b.yaml
# Its Scheduled condition says where it waits: its position from Kueue's visibility API.
positioned=0
for _ in 1 2 3 4 5 6; do
  sleep 5
  phase=$(field team-b survey-b '{.status.phase}')
  a_phase=$(field team-a survey-a '{.status.phase}')
  [ "$a_phase" = Running ] || break
  [ "$phase" = Queued ] || { echo "teams: survey-b is $phase while survey-a still runs" >&2; exit 1; }
  pods=$(kubectl get pods -n team-b -l sadesim.io/run=survey-b -o name | wc -l)
  [ "$pods" -eq 0 ] || { echo "teams: $pods pods of survey-b exist before its admission" >&2; exit 1; }
  scheduled=$(field team-b survey-b '{.status.conditions[?(@.type=="Scheduled")].message}')
  echo "  survey-b: Queued, no pod; $scheduled"
  case "$scheduled" in *"(position "*) positioned=1 ;; esac
done
[ "$positioned" = 1 ] \
  || { echo "teams: survey-b's Scheduled condition never gave its place in the queue (Kueue's visibility API)" >&2; exit 1; }
kubectl get workload -n team-b survey-b -o wide

step "A's run ends; then B's is admitted and runs"
wait_phase team-a survey-a Succeeded
wait_phase team-b survey-b Succeeded
a_done=$(field team-a survey-a '{.status.completionTime}')
b_admitted=$(field team-b survey-b '{.status.conditions[?(@.type=="Scheduled")].lastTransitionTime}')
# RFC 3339 times in UTC compare as strings.
[[ "$b_admitted" > "$a_done" || "$b_admitted" == "$a_done" ]] \
  || { echo "teams: survey-b was admitted at $b_admitted, before survey-a ended at $a_done" >&2; exit 1; }
for ns_run in team-a/survey-a team-b/survey-b; do
  url=$(field "${ns_run%/*}" "${ns_run#*/}" '{.status.archive.url}')
  [ -n "$url" ] || { echo "teams: $ns_run has no archive" >&2; exit 1; }
  echo "  $ns_run archived at $url"
  # The run's Workload is gone with its run: its quota is back in the cohort.
  ! kubectl get workload -n "${ns_run%/*}" "${ns_run#*/}" >/dev/null 2>&1 \
    || { echo "teams: the Workload of $ns_run outlived its run" >&2; exit 1; }
done

step "teams passed ($TOOL): survey-b waited, whole, until survey-a ended at $a_done, and was admitted at $b_admitted"
