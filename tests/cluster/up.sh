#!/usr/bin/env bash
# Brings up a single-node Kubernetes built from upstream source (tests/cluster/build.sh):
# the control plane (etcd, kube-apiserver, kube-controller-manager, kube-scheduler) and the
# node (containerd and runc from Debian, the kubelet, the CNI bridge plugin, kube-proxy in
# iptables mode, CoreDNS as the cluster's DNS) as processes of this machine, with
# certificates made here (openssl) and RBAC on. Prints the admin kubeconfig's path;
# tests/cluster/down.sh removes everything it made (processes, mounts, the bridge, iptables
# rules, sysctls, files).
#
#   KUBECONFIG=$(tests/cluster/up.sh) kubectl get nodes
#   SADESIM_CLUSTER_NODE=0 tests/cluster/up.sh      # the control plane alone (no pod runs)
#
# State (certificates, kubeconfigs, etcd's data, containerd, the kubelet, logs, pid files)
# is in $SADESIM_CLUSTER_DIR (default /var/lib/sadesim-cluster). Refuses to start over a
# cluster that runs. Needs root.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/cluster/lib.sh
. "$here/lib.sh"

with_node=${SADESIM_CLUSTER_NODE:-1}
[ "$(id -u)" -eq 0 ] || { cluster_log "needs root (network, mounts, containers)"; exit 2; }
for tool in openssl curl ip; do
  command -v "$tool" >/dev/null || { cluster_log "$tool not found on PATH"; exit 2; }
done
if [ "$with_node" = 1 ]; then
  for tool in containerd containerd-shim-runc-v2 runc iptables ctr; do
    command -v "$tool" >/dev/null || { cluster_log "$tool not found on PATH (tests/install-tools.sh installs it)"; exit 2; }
  done
  [ -x /usr/lib/cni/bridge ] || { cluster_log "/usr/lib/cni/bridge missing (Debian's containernetworking-plugins)"; exit 2; }
fi
if [ -e "$CLUSTER_DIR" ]; then
  cluster_log "$CLUSTER_DIR exists: run tests/cluster/down.sh first"
  exit 2
fi

bin=$("$here/build.sh")
images=$("$here/images.sh" base)
start=$SECONDS
mkdir -p "$CLUSTER_DIR"
chmod 700 "$CLUSTER_DIR"
echo "$bin" >"$CLUSTER_DIR/bin-dir"

# --- the pods' network, made first: the API server advertises the bridge's address --------
cluster_log "making bridge $POD_BRIDGE ($NODE_IP)"
ip link add "$POD_BRIDGE" type bridge
ip addr add "$NODE_IP/${POD_CIDR#*/}" dev "$POD_BRIDGE"
ip link set "$POD_BRIDGE" up
# Service addresses route to the bridge: this machine's own connections to a Service are
# DNATed by kube-proxy to a pod there, and one made before kube-proxy has the Service's rules
# goes nowhere instead of out of the machine's default route.
ip route add "$SERVICE_CIDR" dev "$POD_BRIDGE"

# --- certificates: one CA signs every serving and client certificate ----------------------
pki=$CLUSTER_DIR/pki
mkdir -p "$pki"
# ca NAME CN: a self-signed CA, pki/NAME.{key,crt}.
ca() {
  openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$pki/$1.key" 2>/dev/null
  openssl req -x509 -new -key "$pki/$1.key" -subj "/CN=$2" -days 7 -sha256 \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature" \
    -out "$pki/$1.crt" 2>/dev/null
}
# cert NAME SUBJECT [SUBJECT_ALT_NAMES]: pki/NAME.{key,crt}, signed by the cluster's CA (or
# by pki/$signer when signer= is set); with names, a serving and client certificate.
cert() {
  local name=$1 subject=$2 sans=${3:-} ext
  openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$pki/$name.key" 2>/dev/null
  openssl req -new -key "$pki/$name.key" -subj "$subject" -out "$pki/$name.csr" 2>/dev/null
  ext="$pki/$name.ext"
  {
    echo "basicConstraints=CA:FALSE"
    echo "keyUsage=critical,digitalSignature,keyEncipherment"
    if [ -n "$sans" ]; then
      echo "extendedKeyUsage=serverAuth,clientAuth"
      echo "subjectAltName=$sans"
    else
      echo "extendedKeyUsage=clientAuth"
    fi
  } >"$ext"
  openssl x509 -req -in "$pki/$name.csr" -CA "$pki/${signer:-ca}.crt" -CAkey "$pki/${signer:-ca}.key" \
    -CAcreateserial -days 7 -sha256 -extfile "$ext" -out "$pki/$name.crt" 2>/dev/null
  rm -f "$pki/$name.csr" "$ext"
}
ca ca sadesim-test-cluster-ca
# The aggregation layer's CA and the API server's client of it (what an aggregated API
# server such as Kueue's visibility API trusts).
ca front-proxy-ca sadesim-test-front-proxy-ca
signer=front-proxy-ca cert front-proxy-client "/CN=front-proxy-client"
cert apiserver "/CN=kube-apiserver" \
  "DNS:kubernetes,DNS:kubernetes.default,DNS:kubernetes.default.svc,DNS:kubernetes.default.svc.cluster.local,DNS:localhost,IP:127.0.0.1,IP:$NODE_IP,IP:$SERVICE_APISERVER_IP"
cert apiserver-kubelet-client "/O=system:masters/CN=kube-apiserver-kubelet-client"
cert admin "/O=system:masters/CN=kubernetes-admin"
cert controller-manager "/CN=system:kube-controller-manager"
cert scheduler "/CN=system:kube-scheduler"
cert kubelet "/O=system:nodes/CN=system:node:$NODE_NAME" "DNS:$NODE_NAME,IP:$NODE_IP"
cert kube-proxy "/CN=system:kube-proxy"
# The service accounts' token signing key pair.
openssl genpkey -algorithm RSA -pkeyopt rsa_keygen_bits:2048 -out "$pki/sa.key" 2>/dev/null
openssl pkey -in "$pki/sa.key" -pubout -out "$pki/sa.pub" 2>/dev/null

# kubeconfig NAME: NAME.kubeconfig for the client certificate pki/NAME.
kubeconfig() {
  local file=$CLUSTER_DIR/$1.kubeconfig
  "$bin/kubectl" config set-cluster sadesim-test --kubeconfig="$file" --server="https://127.0.0.1:$APISERVER_PORT" \
    --certificate-authority="$pki/ca.crt" --embed-certs >/dev/null
  "$bin/kubectl" config set-credentials "$1" --kubeconfig="$file" \
    --client-certificate="$pki/$1.crt" --client-key="$pki/$1.key" --embed-certs >/dev/null
  "$bin/kubectl" config set-context sadesim-test --kubeconfig="$file" --cluster=sadesim-test --user="$1" >/dev/null
  "$bin/kubectl" config use-context sadesim-test --kubeconfig="$file" >/dev/null
  chmod 600 "$file"
}
for user in admin controller-manager scheduler kubelet kube-proxy; do kubeconfig "$user"; done

# --- the control plane ----------------------------------------------------------------------
cluster_log "starting etcd"
cluster_start etcd "$bin/etcd" \
  --name=sadesim-test --data-dir="$CLUSTER_DIR/etcd" \
  --listen-client-urls="http://127.0.0.1:$ETCD_CLIENT_PORT" --advertise-client-urls="http://127.0.0.1:$ETCD_CLIENT_PORT" \
  --listen-peer-urls="http://127.0.0.1:$ETCD_PEER_PORT" --initial-advertise-peer-urls="http://127.0.0.1:$ETCD_PEER_PORT" \
  --initial-cluster="sadesim-test=http://127.0.0.1:$ETCD_PEER_PORT" \
  --listen-metrics-urls=http://127.0.0.1:2381 --log-level=warn
cluster_wait etcd 60 curl -fsS "http://127.0.0.1:2381/health"

# The audit log counts the API requests of the operator's service account (the cost of a
# run in requests, tests/cluster/test_cost.py); everything else is not logged.
cat >"$CLUSTER_DIR/audit-policy.yaml" <<YAML
apiVersion: audit.k8s.io/v1
kind: Policy
omitStages: [RequestReceived]
rules:
  - level: Metadata
    userGroups: [system:serviceaccounts:sadesim-system]
  - level: None
YAML
cluster_log "starting kube-apiserver"
# Listens on 127.0.0.1 (this machine's clients) and on the bridge's address (pods, through
# the `kubernetes` Service). Aggregated APIs and webhooks are reached at their pods'
# addresses (--enable-aggregator-routing), not through Service addresses, which only exist
# once kube-proxy has written their rules.
cluster_start kube-apiserver "$bin/kube-apiserver" \
  --etcd-servers="http://127.0.0.1:$ETCD_CLIENT_PORT" \
  --bind-address=0.0.0.0 --advertise-address="$NODE_IP" --secure-port="$APISERVER_PORT" \
  --cert-dir="$CLUSTER_DIR/apiserver-certs" \
  --tls-cert-file="$pki/apiserver.crt" --tls-private-key-file="$pki/apiserver.key" \
  --client-ca-file="$pki/ca.crt" \
  --requestheader-client-ca-file="$pki/front-proxy-ca.crt" --requestheader-allowed-names=front-proxy-client \
  --requestheader-username-headers=X-Remote-User --requestheader-group-headers=X-Remote-Group \
  --requestheader-extra-headers-prefix=X-Remote-Extra- \
  --proxy-client-cert-file="$pki/front-proxy-client.crt" --proxy-client-key-file="$pki/front-proxy-client.key" \
  --kubelet-client-certificate="$pki/apiserver-kubelet-client.crt" --kubelet-client-key="$pki/apiserver-kubelet-client.key" \
  --kubelet-certificate-authority="$pki/ca.crt" --kubelet-preferred-address-types=InternalIP \
  --service-account-issuer=https://kubernetes.default.svc.cluster.local \
  --service-account-key-file="$pki/sa.pub" --service-account-signing-key-file="$pki/sa.key" \
  --service-cluster-ip-range="$SERVICE_CIDR" \
  --authorization-mode=Node,RBAC --allow-privileged=true --profiling=false \
  --enable-aggregator-routing=true \
  --audit-policy-file="$CLUSTER_DIR/audit-policy.yaml" --audit-log-path="$CLUSTER_DIR/logs/audit.log" \
  --audit-log-maxbackup=1 --audit-log-maxsize=200
cluster_wait kube-apiserver 120 kubectl get --raw /readyz

cluster_log "starting kube-controller-manager and kube-scheduler"
cluster_start kube-controller-manager "$bin/kube-controller-manager" \
  --kubeconfig="$CLUSTER_DIR/controller-manager.kubeconfig" \
  --authentication-kubeconfig="$CLUSTER_DIR/controller-manager.kubeconfig" \
  --authorization-kubeconfig="$CLUSTER_DIR/controller-manager.kubeconfig" \
  --bind-address=127.0.0.1 --leader-elect=false --use-service-account-credentials=true \
  --root-ca-file="$pki/ca.crt" --service-account-private-key-file="$pki/sa.key" \
  --cluster-signing-cert-file="$pki/ca.crt" --cluster-signing-key-file="$pki/ca.key" \
  --service-cluster-ip-range="$SERVICE_CIDR" --profiling=false
cluster_start kube-scheduler "$bin/kube-scheduler" \
  --kubeconfig="$CLUSTER_DIR/scheduler.kubeconfig" \
  --authentication-kubeconfig="$CLUSTER_DIR/scheduler.kubeconfig" \
  --authorization-kubeconfig="$CLUSTER_DIR/scheduler.kubeconfig" \
  --bind-address=127.0.0.1 --leader-elect=false --profiling=false
# Ready when the controller manager has made the default namespace's service account (pods
# need it) and the scheduler answers.
cluster_wait "kube-controller-manager (the default ServiceAccount)" 120 kubectl get serviceaccount default -n default
cluster_wait kube-scheduler 60 curl -fsSk "https://127.0.0.1:10259/healthz"
cluster_log "control plane up in $((SECONDS - start)) s ($(kubectl version -o json | grep -m1 gitVersion | tr -d ' ,'))"

if [ "$with_node" = 1 ]; then
  # shellcheck source=tests/cluster/node.sh
  . "$here/node.sh"
fi

for pidfile in "$CLUSTER_DIR"/pids/*.pid; do
  name=$(basename "$pidfile" .pid)
  cluster_alive "$name" || { cluster_log "$name exited: see $CLUSTER_DIR/logs/$name.log"; exit 1; }
done
echo $((SECONDS - start)) >"$CLUSTER_DIR/up-seconds"
cluster_log "cluster up in $((SECONDS - start)) s"
echo "$CLUSTER_KUBECONFIG"
