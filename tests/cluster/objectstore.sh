#!/usr/bin/env bash
# The test cluster's S3-compatible object store: Versity's S3 gateway (build.sh) over a
# folder of the cluster's, as a process of this machine listening on the node's address, and
# the Service s3.objectstore (port 9000) that points pods at it. down.sh removes it with the
# cluster.
#
#   tests/cluster/objectstore.sh start BUCKET   # serves, with BUCKET made; prints the in-cluster URL
#   tests/cluster/objectstore.sh stop           # the store goes away (the archive-fault test)
#   tests/cluster/objectstore.sh resume         # serves again, the same data
#
# Its credentials are fixed test ones: OBJECTSTORE_ACCESS_KEY / OBJECTSTORE_SECRET_KEY below.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/cluster/lib.sh
. "$here/lib.sh"

OBJECTSTORE_PORT=9000
OBJECTSTORE_ACCESS_KEY=sadesim
OBJECTSTORE_SECRET_KEY=sadesim-e2e-secret
data=$CLUSTER_DIR/objectstore
bin=$(cat "$CLUSTER_DIR/bin-dir")

serve() {
  cluster_start objectstore "$bin/versitygw" --access "$OBJECTSTORE_ACCESS_KEY" --secret "$OBJECTSTORE_SECRET_KEY" \
    --port "$NODE_IP:$OBJECTSTORE_PORT" --port "127.0.0.1:$OBJECTSTORE_PORT" posix "$data"
  cluster_wait objectstore 30 curl -sS -o /dev/null "http://127.0.0.1:$OBJECTSTORE_PORT/"
}

case "${1:-}" in
  start)
    bucket=${2:?usage: $0 start BUCKET}
    # A bucket of the posix backend is a folder of the top folder.
    mkdir -p "$data/$bucket"
    serve
    kubectl apply -f - >/dev/null <<YAML
apiVersion: v1
kind: Namespace
metadata: {name: objectstore}
---
apiVersion: v1
kind: Service
metadata: {name: s3, namespace: objectstore}
spec:
  ports: [{name: s3, port: $OBJECTSTORE_PORT, targetPort: $OBJECTSTORE_PORT}]
---
apiVersion: discovery.k8s.io/v1
kind: EndpointSlice
metadata:
  name: s3-node
  namespace: objectstore
  labels: {kubernetes.io/service-name: s3}
addressType: IPv4
ports: [{name: s3, port: $OBJECTSTORE_PORT, protocol: TCP}]
endpoints: [{addresses: ["$NODE_IP"]}]
YAML
    echo "http://s3.objectstore.svc:$OBJECTSTORE_PORT"
    ;;
  stop)
    pid=$(cat "$CLUSTER_DIR/pids/objectstore.pid")
    kill "$pid"
    while kill -0 "$pid" 2>/dev/null; do sleep 0.2; done
    rm -f "$CLUSTER_DIR/pids/objectstore.pid"
    ;;
  resume) serve ;;
  *) echo "usage: $0 start BUCKET | stop | resume" >&2; exit 2 ;;
esac
