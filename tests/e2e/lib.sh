# shellcheck shell=bash
# Shared steps of the end-to-end scripts (tests/e2e/run.sh, tests/e2e/teams.sh), sourced by
# them. Every function takes what it needs as arguments.

# step MESSAGE: a heading in the script's output.
step() { echo; echo "==> $*"; }

# e2e_require_tools PREFIX k3d|kind: exits 2, naming what is missing, without docker,
# kubectl, the cluster tool, helm, or a Docker engine that answers.
e2e_require_tools() {
  local prefix=$1 tool
  for tool in docker kubectl "$2"; do
    command -v "$tool" >/dev/null || { echo "$prefix: $tool not found on PATH" >&2; exit 2; }
  done
  [ -n "$(e2e_helm)" ] || { echo "$prefix: helm not found (run tests/install-tools.sh)" >&2; exit 2; }
  docker info >/dev/null 2>&1 || { echo "$prefix: no Docker engine answers (docker info failed)" >&2; exit 2; }
}

# e2e_helm: the helm to use, .tools/bin/helm (tests/install-tools.sh) or helm on PATH.
e2e_helm() {
  if [ -x .tools/bin/helm ]; then echo .tools/bin/helm; else command -v helm || true; fi
}

# e2e_create_cluster k3d|kind NAME: a cluster with one agent (k3d) or one node (kind).
e2e_create_cluster() {
  case "$1" in
    k3d) k3d cluster create "$2" --agents 1 --wait --timeout 180s ;;
    kind) kind create cluster --name "$2" --wait 180s ;;
  esac
  kubectl cluster-info
}

# e2e_delete_cluster k3d|kind NAME
e2e_delete_cluster() {
  case "$1" in
    k3d) k3d cluster delete "$2" || true ;;
    kind) kind delete cluster --name "$2" || true ;;
  esac
}

# e2e_import_images k3d|kind CLUSTER IMAGE...: images built locally, into the cluster's
# nodes (no registry).
e2e_import_images() {
  local tool=$1 cluster=$2
  shift 2
  case "$tool" in
    k3d) k3d image import -c "$cluster" "$@" ;;
    kind) kind load docker-image --name "$cluster" "$@" ;;
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

# e2e_install_chart HELM SYSTEM_NS TAG BUCKET USER PASSWORD RUN_NAMESPACES [HELM ARGS...]:
# the chart with the images of TAG, archiving to s3://BUCKET on the MinIO above, its
# credentials copied into each of RUN_NAMESPACES (comma-separated).
e2e_install_chart() {
  local helm=$1 system_ns=$2 tag=$3 bucket=$4 user=$5 password=$6 namespaces=$7
  shift 7
  "$helm" upgrade --install sadesim charts/sadesim -n "$system_ns" --create-namespace --wait --timeout 180s \
    --set image.tag="$tag" \
    --set workerImage.tag="$tag" \
    --set cameraImage.tag="$tag" \
    --set defaultArchiveUrl="s3://$bucket" \
    --set objectStore.create=true \
    --set objectStore.secretName=sadesim-object-store \
    --set "objectStore.namespaces={$namespaces}" \
    --set objectStore.env.AWS_ACCESS_KEY_ID="$user" \
    --set objectStore.env.AWS_SECRET_ACCESS_KEY="$password" \
    --set objectStore.env.AWS_REGION=us-east-1 \
    --set objectStore.env.AWS_ENDPOINT_URL=http://minio.minio.svc:9000 \
    --set-string objectStore.env.AWS_ALLOW_HTTP=true \
    "$@"
  kubectl get crd simulationruns.sadesim.io
}
