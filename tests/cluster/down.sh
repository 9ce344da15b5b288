#!/usr/bin/env bash
# Removes the test cluster of tests/cluster/up.sh and everything it made on this machine:
# the pods' processes and cgroups, every process up.sh started (each names the cluster's
# directory in its command line), every mount under that directory, the iptables chains and
# rules of kube-proxy, the kubelet and the CNI plugins, the bridge and its veths, the sysctls
# it changed, CNI's cache files, and the directory itself. Safe to run when nothing is up.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/cluster/lib.sh
. "$here/lib.sh"

# stop PIDS...: SIGTERM, then SIGKILL for what is left after 10 s.
stop() {
  [ $# -gt 0 ] || return 0
  kill -s TERM "$@" 2>/dev/null || true
  for _ in $(seq 1 20); do
    kill -0 "$@" 2>/dev/null || return 0
    sleep 0.5
  done
  kill -s KILL "$@" 2>/dev/null || true
  sleep 0.5
}
# Processes that name the cluster's directory (control plane, containerd, its shims, the kubelet).
cluster_pids() { pgrep -f -- "$CLUSTER_DIR/" || true; }
# The pods' cgroups (the kubelet's cgroupfs driver: kubepods under each v1 controller).
pod_cgroups() { find /sys/fs/cgroup/*/kubepods -depth -type d 2>/dev/null || true; }
pod_pids() {
  local cg
  for cg in $(pod_cgroups); do cat "$cg/cgroup.procs" 2>/dev/null || true; done | sort -u
}

# 1. The kubelet first, so that nothing restarts the containers; then the pods' processes.
if [ -f "$CLUSTER_DIR/pids/kubelet.pid" ]; then
  stop "$(cat "$CLUSTER_DIR/pids/kubelet.pid")"
fi
# shellcheck disable=SC2046
stop $(pod_pids)
# 2. Everything else the cluster started.
# shellcheck disable=SC2046
stop $(cluster_pids)
left="$(cluster_pids) $(pod_pids)"
if [ -n "${left// /}" ]; then
  cluster_log "processes outlived SIGKILL: $left"
  exit 1
fi

# 3. Mounts under the cluster's directory (container root filesystems, shm, network
# namespaces, the kubelet's volumes), deepest first.
if [ -d "$CLUSTER_DIR" ]; then
  awk -v dir="$CLUSTER_DIR/" 'index($5, dir) == 1 { print $5 }' /proc/self/mountinfo | sort -r | while read -r m; do
    umount "$m" 2>/dev/null || umount -l "$m"
  done
fi
for cg in $(pod_cgroups); do rmdir "$cg" 2>/dev/null || true; done
[ -z "$(pod_cgroups)" ] || { cluster_log "cgroups left: $(pod_cgroups | head -3)"; exit 1; }

# 4. iptables: kube-proxy's own cleanup, then every chain named KUBE-* or CNI-* and every
# rule that jumps to one or carries up.sh's comment.
if [ -f "$CLUSTER_DIR/bin-dir" ] && [ -x "$(cat "$CLUSTER_DIR/bin-dir")/kube-proxy" ]; then
  "$(cat "$CLUSTER_DIR/bin-dir")/kube-proxy" --cleanup >/dev/null 2>&1 || true
fi
for family in iptables ip6tables; do
  command -v "$family-save" >/dev/null || continue
  if "$family-save" | grep -qE 'KUBE-|CNI-|sadesim-test-cluster'; then
    "$family-save" | grep -vE '^:(KUBE-|CNI-)|^-A (KUBE-|CNI-)|-j (KUBE-|CNI-)|sadesim-test-cluster' | "$family-restore"
  fi
done

# 5. The bridge (its veths went with the pods' network namespaces) and CNI's cache.
if ip link show "$POD_BRIDGE" >/dev/null 2>&1; then
  for veth in $(ip -o link show master "$POD_BRIDGE" | awk -F': ' '{print $2}' | cut -d@ -f1); do
    ip link del "$veth" 2>/dev/null || true
  done
  ip link del "$POD_BRIDGE"
fi
rm -f /var/lib/cni/results/"$CNI_NETWORK"-* 2>/dev/null || true

# 6. The sysctls up.sh changed, back to their values before it.
if [ -d "$CLUSTER_DIR/host" ]; then
  for file in "$CLUSTER_DIR"/host/*; do
    [ -f "$file" ] && sysctl -qw "$(basename "$file")=$(cat "$file")"
  done
fi

rm -rf "$CLUSTER_DIR"
cluster_log "down: no process, mount, cgroup, bridge or iptables rule of the cluster left; $CLUSTER_DIR removed"
