# shellcheck shell=bash
# shellcheck disable=SC2034  # the variables are for the scripts that source this file
# Shared parts of tests/cluster/up.sh and down.sh: where the cluster's state lives and how
# its processes are started and stopped.

# shellcheck source=tests/cluster/versions.sh
. "$(dirname "${BASH_SOURCE[0]}")/versions.sh"

# Everything the cluster writes (certificates, kubeconfigs, etcd's data, logs, pid files)
# is under this directory, outside the clone; down.sh removes it.
CLUSTER_DIR=${SADESIM_CLUSTER_DIR:-/var/lib/sadesim-cluster}
# The admin kubeconfig (system:masters) that tests and scripts use.
CLUSTER_KUBECONFIG=$CLUSTER_DIR/admin.kubeconfig

# Ports of the control plane (etcd on 127.0.0.1 only).
ETCD_CLIENT_PORT=2379
ETCD_PEER_PORT=2380
APISERVER_PORT=6443
# The Service network; its first address is the `kubernetes` Service, the tenth the
# cluster's DNS.
SERVICE_CIDR=10.96.0.0/16
SERVICE_APISERVER_IP=10.96.0.1
SERVICE_DNS_IP=10.96.0.10
# The pods' network: a bridge of this machine's (made by up.sh, used by the CNI bridge
# plugin) whose address is also the node's and the one the API server advertises, so pods
# reach the API server and the kubelet without any address outside the machine.
POD_BRIDGE=sadesim0
POD_CIDR=10.244.0.0/24
NODE_IP=10.244.0.1
NODE_NAME=sadesim-node
# The CNI network's name (containerd's CNI cache files carry it).
CNI_NETWORK=sadesim-test
# containerd's socket; short, since unix socket paths are limited to 107 bytes.
CONTAINERD_SOCKET=$CLUSTER_DIR/containerd.sock

# kubectl ARGS...: the cluster's own kubectl (the build up.sh recorded in bin-dir) with the
# admin kubeconfig.
kubectl() { "$(cat "$CLUSTER_DIR/bin-dir")/kubectl" --kubeconfig="$CLUSTER_KUBECONFIG" "$@"; }

# cluster_log MESSAGE
cluster_log() { echo "cluster: $*" >&2; }

# cluster_start NAME COMMAND...: starts COMMAND in its own session, its output in
# logs/NAME.log and its pid in pids/NAME.pid.
cluster_start() {
  local name=$1
  shift
  mkdir -p "$CLUSTER_DIR/logs" "$CLUSTER_DIR/pids"
  setsid "$@" </dev/null >"$CLUSTER_DIR/logs/$name.log" 2>&1 &
  echo $! >"$CLUSTER_DIR/pids/$name.pid"
}

# cluster_alive NAME: whether the process started as NAME still runs.
cluster_alive() {
  local pid
  pid=$(cat "$CLUSTER_DIR/pids/$1.pid" 2>/dev/null) || return 1
  kill -0 "$pid" 2>/dev/null
}

# cluster_wait WHAT SECONDS COMMAND...: retries COMMAND each second until it succeeds; after
# SECONDS it fails naming WHAT.
cluster_wait() {
  local what=$1 seconds=$2 deadline
  shift 2
  deadline=$((SECONDS + seconds))
  until "$@" >/dev/null 2>&1; do
    if [ "$SECONDS" -ge "$deadline" ]; then
      cluster_log "$what: not ready after ${seconds} s"
      return 1
    fi
    sleep 1
  done
}
