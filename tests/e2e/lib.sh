# shellcheck shell=bash
# Shared steps of the end-to-end scripts (tests/e2e/run.sh, tests/e2e/teams.sh), sourced by
# them. Every function takes what it needs as arguments.

# step MESSAGE: a heading in the script's output.
step() { echo; echo "==> $*"; }

# e2e_require_tools PREFIX k3d|kind|local: exits 2, naming what is missing, without docker,
# kubectl, the cluster tool, helm, or a Docker engine that answers; for local (the cluster of
# tests/cluster/, built here from upstream source), without go, buildah, containerd or helm.
e2e_require_tools() {
  local prefix=$1 tool
  [ -n "$(e2e_helm)" ] || { echo "$prefix: helm not found (run tests/install-tools.sh)" >&2; exit 2; }
  if [ "$2" = local ]; then
    for tool in go buildah containerd runc; do
      command -v "$tool" >/dev/null || { echo "$prefix: $tool not found on PATH (run tests/install-tools.sh)" >&2; exit 2; }
    done
    return
  fi
  for tool in docker kubectl "$2"; do
    command -v "$tool" >/dev/null || { echo "$prefix: $tool not found on PATH" >&2; exit 2; }
  done
  docker info >/dev/null 2>&1 || { echo "$prefix: no Docker engine answers (docker info failed)" >&2; exit 2; }
}

# e2e_helm: the helm to use, .tools/bin/helm (tests/install-tools.sh) or helm on PATH.
e2e_helm() {
  if [ -x .tools/bin/helm ]; then echo .tools/bin/helm; else command -v helm || true; fi
}

# e2e_create_cluster k3d|kind|local NAME: a cluster with one agent (k3d) or one node (kind,
# local). local exports KUBECONFIG and puts the cluster's kubectl first on PATH.
e2e_create_cluster() {
  case "$1" in
    k3d) k3d cluster create "$2" --agents 1 --wait --timeout 180s ;;
    kind) kind create cluster --name "$2" --wait 180s ;;
    local)
      tests/cluster/down.sh
      KUBECONFIG=$(tests/cluster/up.sh)
      PATH="$(tests/cluster/build.sh):$PATH"
      export KUBECONFIG PATH ;;
  esac
  kubectl cluster-info
}

# e2e_delete_cluster k3d|kind|local NAME
e2e_delete_cluster() {
  case "$1" in
    k3d) k3d cluster delete "$2" || true ;;
    kind) kind delete cluster --name "$2" || true ;;
    local) tests/cluster/down.sh ;;
  esac
}

# e2e_build_images k3d|kind|local TAG: the operator, worker and camera images tagged TAG and
# the example pilots' image, as the cluster tool takes them: docker build from images/, or for
# local, tests/cluster/images.sh product (the same layout from this machine's build) into
# $E2E_IMAGE_DIR (a new folder, or the one given, left as it is when it holds the images).
e2e_build_images() {
  local tool=$1 tag=$2
  case "$tool" in
    local)
      if [ -z "${E2E_IMAGE_DIR:-}" ] || [ ! -f "$E2E_IMAGE_DIR/sim-worker.tar" ]; then
        E2E_IMAGE_DIR=${E2E_IMAGE_DIR:-$(mktemp -d)}
        tests/cluster/images.sh product "$tag" "$E2E_IMAGE_DIR"
      fi ;;
    *)
      docker build -f images/operator.Dockerfile -t "ghcr.io/sadesim/sadesim:$tag" .
      docker build -f images/sim-worker.Dockerfile -t "ghcr.io/sadesim/sim-worker:$tag" .
      docker build -f images/sim-worker-camera.Dockerfile -t "ghcr.io/sadesim/sim-worker-camera:$tag" .
      docker build -f images/pilot-python.Dockerfile -t ghcr.io/sadesim/pilot-python:0.1.0 .
      docker build -f images/pilot-examples.Dockerfile --build-arg BASE=ghcr.io/sadesim/pilot-python:0.1.0 \
        -t ghcr.io/sadesim/pilot-examples:0.1.0 . ;;
  esac
}

# e2e_import_images k3d|kind|local CLUSTER IMAGE...: images built locally, into the cluster's
# nodes (no registry); local imports them from the images e2e_build_images made, with the
# busybox image tests/e2e/pilot-exit.yaml names (k3d and kind pull that one themselves).
e2e_import_images() {
  local tool=$1 cluster=$2
  shift 2
  case "$tool" in
    k3d) k3d image import -c "$cluster" "$@" ;;
    kind) kind load docker-image --name "$cluster" "$@" ;;
    local) tests/cluster/images.sh import "$E2E_IMAGE_DIR" "$@" docker.io/library/busybox:1.36 ;;
  esac
}

# e2e_start_object_store k3d|kind|local USER PASSWORD BUCKET: an S3 store with BUCKET made;
# prints its URL inside the cluster. k3d and kind run MinIO in the cluster (namespace minio);
# local runs Versity's S3 gateway on the node (tests/cluster/objectstore.sh), whose fixed
# credentials are USER and PASSWORD.
e2e_start_object_store() {
  local tool=$1 user=$2 password=$3 bucket=$4
  case "$tool" in
    local) tests/cluster/objectstore.sh start "$bucket" ;;
    *)
      e2e_start_minio "${MINIO_IMAGE:-quay.io/minio/minio:latest}" "${MC_IMAGE:-quay.io/minio/mc:latest}" \
        "$user" "$password" "$bucket" >&2
      echo http://minio.minio.svc:9000 ;;
  esac
}

# e2e_start_minio MINIO_IMAGE MC_IMAGE USER PASSWORD BUCKET: MinIO in namespace minio,
# Service minio:9000, with BUCKET made.
e2e_start_minio() {
  local minio_image=$1 mc_image=$2 user=$3 password=$4 bucket=$5
  kubectl create namespace minio --dry-run=client -o yaml | kubectl apply -f -
  kubectl apply -n minio -f - <<YAML
apiVersion: apps/v1
kind: Deployment
metadata: {name: minio}
spec:
  selector: {matchLabels: {app: minio}}
  template:
    metadata: {labels: {app: minio}}
    spec:
      containers:
        - name: minio
          image: $minio_image
          args: [server, /data]
          env:
            - {name: MINIO_ROOT_USER, value: $user}
            - {name: MINIO_ROOT_PASSWORD, value: $password}
          ports: [{containerPort: 9000}]
          readinessProbe: {httpGet: {path: /minio/health/ready, port: 9000}}
          volumeMounts: [{name: data, mountPath: /data}]
      volumes: [{name: data, emptyDir: {}}]
---
apiVersion: v1
kind: Service
metadata: {name: minio}
spec:
  selector: {app: minio}
  ports: [{port: 9000, targetPort: 9000}]
YAML
  kubectl rollout status -n minio deployment/minio --timeout=180s
  kubectl delete job -n minio make-bucket --ignore-not-found
  kubectl apply -n minio -f - <<YAML
apiVersion: batch/v1
kind: Job
metadata: {name: make-bucket}
spec:
  backoffLimit: 3
  template:
    spec:
      restartPolicy: Never
      containers:
        - name: mc
          image: $mc_image
          command: [sh, -c, "mc alias set e2e http://minio:9000 $user $password && mc mb --ignore-existing e2e/$bucket"]
YAML
  kubectl wait -n minio --for=condition=complete job/make-bucket --timeout=180s
}

# e2e_install_chart HELM SYSTEM_NS TAG BUCKET USER PASSWORD RUN_NAMESPACES ENDPOINT [HELM ARGS...]:
# the chart with the images of TAG, archiving to s3://BUCKET on the object store at ENDPOINT,
# its credentials copied into each of RUN_NAMESPACES (comma-separated).
e2e_install_chart() {
  local helm=$1 system_ns=$2 tag=$3 bucket=$4 user=$5 password=$6 namespaces=$7 endpoint=$8
  shift 8
  "$helm" upgrade --install sadesim charts/sadesim -n "$system_ns" --create-namespace --wait --timeout 180s \
    --set image.tag="$tag" \
    --set workerImage.tag="$tag" \
    --set cameraImage.tag="$tag" \
    --set openfoamImage.tag="$tag" \
    --set defaultArchiveUrl="s3://$bucket" \
    --set objectStore.create=true \
    --set objectStore.secretName=sadesim-object-store \
    --set "objectStore.namespaces={$namespaces}" \
    --set objectStore.env.AWS_ACCESS_KEY_ID="$user" \
    --set objectStore.env.AWS_SECRET_ACCESS_KEY="$password" \
    --set objectStore.env.AWS_REGION=us-east-1 \
    --set objectStore.env.AWS_ENDPOINT_URL="$endpoint" \
    --set-string objectStore.env.AWS_ALLOW_HTTP=true \
    "$@"
  kubectl get crd simulationruns.sadesim.io
}
