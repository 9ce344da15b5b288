# shellcheck shell=bash
# shellcheck disable=SC2154  # $here, $bin, $pki and $images are up.sh's
# The node of tests/cluster/up.sh (sourced by it, after the control plane): host settings,
# containerd, the kubelet, kube-proxy and CoreDNS. Uses up.sh's variables ($bin, $pki,
# $images) and functions (kubectl).

# --- host settings, each restored by down.sh --------------------------------------------------
# Services need the bridge's traffic to pass iptables (br_netfilter) and the host to route
# between the bridge and Service addresses. The old values are kept for down.sh.
mkdir -p "$CLUSTER_DIR/host"
modprobe br_netfilter 2>/dev/null || true
for key in net.ipv4.ip_forward net.bridge.bridge-nf-call-iptables; do
  [ -e "/proc/sys/${key//.//}" ] || { cluster_log "/proc/sys/${key//.//} missing (br_netfilter?)"; exit 1; }
  sysctl -n "$key" >"$CLUSTER_DIR/host/$key"
  sysctl -qw "$key=1"
done
# Pods reach each other, the node and Services, and nothing beyond this machine: what they
# send out of any other interface is dropped (comment sadesim-test-cluster, removed by down.sh).
iptables -I FORWARD 1 -s "$POD_CIDR" ! -o "$POD_BRIDGE" -m comment --comment sadesim-test-cluster -j DROP

# --- containerd -------------------------------------------------------------------------------
mkdir -p "$CLUSTER_DIR/containerd" "$CLUSTER_DIR/cni/net.d"
cat >"$CLUSTER_DIR/containerd/config.toml" <<TOML
version = 2
root = "$CLUSTER_DIR/containerd/root"
state = "$CLUSTER_DIR/containerd/state"
disabled_plugins = ["io.containerd.snapshotter.v1.aufs", "io.containerd.snapshotter.v1.btrfs",
  "io.containerd.snapshotter.v1.devmapper", "io.containerd.snapshotter.v1.zfs",
  "io.containerd.tracing.processor.v1.otlp", "io.containerd.internal.v1.tracing"]
[grpc]
  address = "$CONTAINERD_SOCKET"
[plugins."io.containerd.grpc.v1.cri"]
  sandbox_image = "$PAUSE_IMAGE"
  enable_unprivileged_ports = true
  # This machine's root lacks CAP_SYS_RESOURCE, so nothing may lower an OOM score below
  # containerd's own (the kubelet asks -998 for pod sandboxes): clamp, as rootless setups do.
  restrict_oom_score_adj = true
  # Network namespaces under containerd's state, so that down.sh finds every one.
  netns_mounts_under_state_dir = true
  [plugins."io.containerd.grpc.v1.cri".containerd]
    snapshotter = "overlayfs"
    default_runtime_name = "runc"
    [plugins."io.containerd.grpc.v1.cri".containerd.runtimes.runc]
      runtime_type = "io.containerd.runc.v2"
      [plugins."io.containerd.grpc.v1.cri".containerd.runtimes.runc.options]
        SystemdCgroup = false
        Root = "$CLUSTER_DIR/containerd/runc"
  # No registry is reachable from here: every registry a manifest names is this machine's
  # closed port, so a missing image fails at once (ErrImagePull) and nothing is looked up.
  [plugins."io.containerd.grpc.v1.cri".registry]
    config_path = "$CLUSTER_DIR/containerd/certs.d"
  [plugins."io.containerd.grpc.v1.cri".cni]
    bin_dir = "/usr/lib/cni"
    conf_dir = "$CLUSTER_DIR/cni/net.d"
[plugins."io.containerd.internal.v1.opt"]
  path = "$CLUSTER_DIR/containerd/opt"
TOML
cat >"$CLUSTER_DIR/cni/net.d/10-$CNI_NETWORK.conflist" <<JSON
{
  "cniVersion": "1.0.0",
  "name": "$CNI_NETWORK",
  "plugins": [
    {
      "type": "bridge",
      "bridge": "$POD_BRIDGE",
      "isGateway": true,
      "ipMasq": false,
      "hairpinMode": true,
      "ipam": {
        "type": "host-local",
        "ranges": [[{"subnet": "$POD_CIDR", "gateway": "$NODE_IP"}]],
        "routes": [{"dst": "0.0.0.0/0"}],
        "dataDir": "$CLUSTER_DIR/cni/ipam"
      }
    },
    {"type": "portmap", "capabilities": {"portMappings": true}}
  ]
}
JSON
for registry in _default docker.io ghcr.io gcr.io quay.io registry.k8s.io; do
  mkdir -p "$CLUSTER_DIR/containerd/certs.d/$registry"
  echo 'server = "http://127.0.0.1:9"' >"$CLUSTER_DIR/containerd/certs.d/$registry/hosts.toml"
done
cluster_log "starting containerd"
cluster_start containerd containerd --config "$CLUSTER_DIR/containerd/config.toml"
cluster_wait containerd 60 ctr --address "$CONTAINERD_SOCKET" version
"$here/images.sh" import "$images"

# --- the kubelet ------------------------------------------------------------------------------
# The pods' resolv.conf for dnsPolicy Default: no name server of this machine's (pods ask the
# cluster's DNS, which answers cluster names only).
echo "options ndots:1" >"$CLUSTER_DIR/resolv.conf"
cat >"$CLUSTER_DIR/kubelet.yaml" <<YAML
apiVersion: kubelet.config.k8s.io/v1beta1
kind: KubeletConfiguration
address: $NODE_IP
readOnlyPort: 0
healthzBindAddress: 127.0.0.1
authentication:
  anonymous: {enabled: false}
  webhook: {enabled: true}
  x509: {clientCAFile: $pki/ca.crt}
authorization: {mode: Webhook}
tlsCertFile: $pki/kubelet.crt
tlsPrivateKeyFile: $pki/kubelet.key
containerRuntimeEndpoint: unix://$CONTAINERD_SOCKET
# Debian's containerd 1.6 does not report its cgroup driver (the RuntimeConfig call).
cgroupDriver: cgroupfs
# This machine has cgroup v1, which the kubelet refuses by default from 1.35 on.
failCgroupV1: false
failSwapOn: false
# Not -999: without CAP_SYS_RESOURCE no process here may lower its OOM score.
oomScoreAdj: 0
clusterDNS: [$SERVICE_DNS_IP]
clusterDomain: cluster.local
resolvConf: $CLUSTER_DIR/resolv.conf
podLogsDir: $CLUSTER_DIR/pod-logs
serializeImagePulls: false
# No image is ever pulled (none can be): the kubelet must not collect the imported ones.
imageGCHighThresholdPercent: 100
imageGCLowThresholdPercent: 99
evictionHard: {memory.available: 200Mi, nodefs.available: 2%, imagefs.available: 2%}
YAML
cluster_log "starting the kubelet"
cluster_start kubelet "$bin/kubelet" \
  --config="$CLUSTER_DIR/kubelet.yaml" --kubeconfig="$CLUSTER_DIR/kubelet.kubeconfig" \
  --root-dir="$CLUSTER_DIR/kubelet" --cert-dir="$CLUSTER_DIR/kubelet/pki" \
  --hostname-override="$NODE_NAME" --node-ip="$NODE_IP"

# --- kube-proxy -------------------------------------------------------------------------------
cluster_log "starting kube-proxy"
cluster_start kube-proxy "$bin/kube-proxy" \
  --kubeconfig="$CLUSTER_DIR/kube-proxy.kubeconfig" --hostname-override="$NODE_NAME" \
  --proxy-mode=iptables --cluster-cidr="$POD_CIDR" --nodeport-addresses="$NODE_IP/32" \
  --conntrack-max-per-core=0 --oom-score-adj=0 --bind-address=127.0.0.1 --healthz-bind-address=127.0.0.1:10256 \
  --metrics-bind-address=127.0.0.1:10249

cluster_wait "node $NODE_NAME Ready" 120 \
  sh -c "'$bin/kubectl' --kubeconfig='$CLUSTER_KUBECONFIG' get node '$NODE_NAME' -o jsonpath='{.status.conditions[?(@.type==\"Ready\")].status}' | grep -qx True"
cluster_wait kube-proxy 60 curl -fsS http://127.0.0.1:10256/healthz

# --- the cluster's DNS ------------------------------------------------------------------------
cluster_log "starting CoreDNS (Service kube-dns, $SERVICE_DNS_IP)"
kubectl apply -f - >/dev/null <<YAML
apiVersion: v1
kind: ServiceAccount
metadata: {name: coredns, namespace: kube-system}
---
apiVersion: rbac.authorization.k8s.io/v1
kind: ClusterRole
metadata: {name: system:coredns}
rules:
  - apiGroups: [""]
    resources: [endpoints, services, pods, namespaces]
    verbs: [list, watch]
  - apiGroups: [discovery.k8s.io]
    resources: [endpointslices]
    verbs: [list, watch]
---
apiVersion: rbac.authorization.k8s.io/v1
kind: ClusterRoleBinding
metadata: {name: system:coredns}
roleRef: {apiGroup: rbac.authorization.k8s.io, kind: ClusterRole, name: system:coredns}
subjects: [{kind: ServiceAccount, name: coredns, namespace: kube-system}]
---
apiVersion: v1
kind: ConfigMap
metadata: {name: coredns, namespace: kube-system}
data:
  Corefile: |
    .:53 {
        errors
        health :8080
        ready :8181
        kubernetes cluster.local in-addr.arpa ip6.arpa {
            pods insecure
            fallthrough in-addr.arpa ip6.arpa
        }
        cache 30
        reload
    }
---
apiVersion: apps/v1
kind: Deployment
metadata: {name: coredns, namespace: kube-system, labels: {k8s-app: kube-dns}}
spec:
  replicas: 1
  selector: {matchLabels: {k8s-app: kube-dns}}
  template:
    metadata: {labels: {k8s-app: kube-dns}}
    spec:
      serviceAccountName: coredns
      dnsPolicy: Default
      priorityClassName: system-cluster-critical
      containers:
        - name: coredns
          image: $COREDNS_IMAGE
          imagePullPolicy: Never
          args: [-conf, /etc/coredns/Corefile]
          ports:
            - {name: dns, containerPort: 53, protocol: UDP}
            - {name: dns-tcp, containerPort: 53, protocol: TCP}
          readinessProbe: {httpGet: {path: /ready, port: 8181}}
          livenessProbe: {httpGet: {path: /health, port: 8080}}
          securityContext:
            allowPrivilegeEscalation: false
            readOnlyRootFilesystem: true
            capabilities: {add: [NET_BIND_SERVICE], drop: [ALL]}
          volumeMounts: [{name: config, mountPath: /etc/coredns, readOnly: true}]
      volumes: [{name: config, configMap: {name: coredns}}]
---
apiVersion: v1
kind: Service
metadata: {name: kube-dns, namespace: kube-system, labels: {k8s-app: kube-dns}}
spec:
  clusterIP: $SERVICE_DNS_IP
  selector: {k8s-app: kube-dns}
  ports:
    - {name: dns, port: 53, protocol: UDP}
    - {name: dns-tcp, port: 53, protocol: TCP}
YAML
kubectl rollout status -n kube-system deployment/coredns --timeout=180s >&2
