#!/usr/bin/env bash
# Builds the test cluster's binaries from upstream source through the Go module proxy
# (tests/cluster/build/go.mod) into a cache outside the clone, keyed by the versions and the
# build module, and prints the cache's bin directory. A second run finds them and builds
# nothing.
#
#   tests/cluster/build.sh            # prints e.g. /var/cache/sadesim-cluster/k8s-v1.34.4-1a2b3c4d/bin
#
# SADESIM_CLUSTER_CACHE sets the cache's root (default /var/cache/sadesim-cluster). The cold
# build time is written to the cache's build-seconds file (docs/kubernetes.md quotes it).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/cluster/versions.sh
. "$here/versions.sh"

cache_root=${SADESIM_CLUSTER_CACHE:-/var/cache/sadesim-cluster}
key=$(cat "$here/versions.sh" "$here/build.sh" "$here/build/go.mod" "$here/build/go.sum" "$here/build/cmd/etcd/main.go" \
  | sha256sum | cut -c1-12)
dir="$cache_root/k8s-$KUBERNETES_VERSION-$key"
bins=(etcd kube-apiserver kube-controller-manager kube-scheduler kubectl kubelet kube-proxy coredns versitygw kueue)

if [ -f "$dir/complete" ]; then
  echo "$dir/bin"
  exit 0
fi

# The pins of versions.sh must be the build module's.
grep -q "k8s.io/kubernetes $KUBERNETES_VERSION\$" "$here/build/go.mod" \
  || { echo "build.sh: build/go.mod does not require k8s.io/kubernetes $KUBERNETES_VERSION" >&2; exit 2; }
grep -q "go.etcd.io/etcd/server/v3 $ETCD_VERSION\$" "$here/build/go.mod" \
  || { echo "build.sh: build/go.mod does not require go.etcd.io/etcd/server/v3 $ETCD_VERSION" >&2; exit 2; }
command -v go >/dev/null || { echo "build.sh: go not found on PATH" >&2; exit 2; }

minor=${KUBERNETES_VERSION#v1.}
minor=${minor%%.*}
# What Kubernetes' hack/lib/version.sh stamps, or kubectl and the API server say v0.0.0.
ldflags="-s -w"
for pkg in k8s.io/component-base/version k8s.io/client-go/pkg/version; do
  ldflags+=" -X '$pkg.gitVersion=$KUBERNETES_VERSION' -X '$pkg.gitMajor=1' -X '$pkg.gitMinor=$minor'"
  ldflags+=" -X '$pkg.gitTreeState=clean' -X '$pkg.buildDate=1970-01-01T00:00:00Z'"
done

echo "build.sh: building Kubernetes $KUBERNETES_VERSION, etcd $ETCD_VERSION, CoreDNS $COREDNS_VERSION, versitygw $VERSITYGW_VERSION and Kueue $KUEUE_VERSION into $dir (cold: about 16 minutes on 2 cores)" >&2
rm -rf "$dir.tmp"
mkdir -p "$dir.tmp/bin"
start=$SECONDS
(
  cd "$here/build"
  # GOFLAGS=-mod=mod: the build module has a go.sum and no vendor directory.
  CGO_ENABLED=0 GOFLAGS=-mod=mod go build -trimpath -ldflags "$ldflags" -o "$dir.tmp/bin/" \
    ./cmd/etcd \
    k8s.io/kubernetes/cmd/kube-apiserver \
    k8s.io/kubernetes/cmd/kube-controller-manager \
    k8s.io/kubernetes/cmd/kube-scheduler \
    k8s.io/kubernetes/cmd/kubectl \
    k8s.io/kubernetes/cmd/kubelet \
    k8s.io/kubernetes/cmd/kube-proxy
)
# CoreDNS has a module of its own with no replace directives: go install takes it as it is.
CGO_ENABLED=0 GOBIN="$dir.tmp/bin" go install -trimpath -ldflags "-s -w" "github.com/coredns/coredns@$COREDNS_VERSION"
CGO_ENABLED=0 GOBIN="$dir.tmp/bin" go install -trimpath -ldflags "-s -w" \
  "github.com/versity/versitygw/cmd/versitygw@$VERSITYGW_VERSION"
CGO_ENABLED=0 GOBIN="$dir.tmp/bin" go install -trimpath -ldflags "-s -w" "sigs.k8s.io/kueue/cmd/kueue@$KUEUE_VERSION"
for b in "${bins[@]}"; do
  [ -x "$dir.tmp/bin/$b" ] || { echo "build.sh: $b was not built" >&2; exit 1; }
done
echo $((SECONDS - start)) > "$dir.tmp/build-seconds"
touch "$dir.tmp/complete"
rm -rf "$dir"
mv "$dir.tmp" "$dir"
echo "build.sh: built in $((SECONDS - start)) s" >&2
echo "$dir/bin"
