#!/usr/bin/env bash
# Container images of the test cluster, built here (no registry is reachable) with buildah
# and kept as docker-archive tarballs in a cache outside the clone.
#
#   tests/cluster/images.sh base          # the pause (pod sandbox) and CoreDNS images; prints their folder
#   tests/cluster/images.sh product TAG DIR  # the project's images, tagged TAG, into DIR
#   tests/cluster/images.sh import DIR    # every DIR/*.tar into the cluster's containerd (k8s.io namespace)
#
# The base images are scratch images holding one static binary: pause from Kubernetes'
# build/pause/linux/pause.c (the k8s.io/kubernetes module), CoreDNS and Kueue from build.sh.
#
# The project's images are what images/*.Dockerfile make, packed from this machine's own
# build instead of a builder stage and a registry's base image (neither can be had here):
# the same names, files, user (65532) and entrypoint, on a root made of the binaries and
# the Debian 12 shared libraries they link (what distroless/cc-debian12 holds: glibc,
# libgcc, CA certificates, a nonroot user). The camera image adds Mesa's lavapipe Vulkan
# driver with its libraries and ICD file, as images/sim-worker-camera.Dockerfile installs
# them. The binaries are the workspace's dev build (optimised; debug info stripped), from
# $CARGO_TARGET_DIR (default target/). docker.io/library/busybox:1.36, the pilot of
# tests/e2e/pilot-exit.yaml, is Debian's busybox-static.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
# shellcheck source=tests/cluster/lib.sh
. "$here/lib.sh"

cache_root=${SADESIM_CLUSTER_CACHE:-/var/cache/sadesim-cluster}
buildah() { command buildah --storage-driver vfs "$@"; }

# scratch_image NAME TARBALL USER ENTRYPOINT_JSON SRC:DST...: an image from scratch with the
# given files (root_image of a folder holding them), saved as a docker-archive tarball
# tagged NAME.
scratch_image() {
  local name=$1 tarball=$2 user=$3 entrypoint=$4 root file
  shift 4
  root=$(mktemp -d)
  chmod 755 "$root"
  for file in "$@"; do
    mkdir -p "$root$(dirname "${file#*:}")"
    cp "${file%%:*}" "$root${file#*:}"
  done
  root_image "$name" "$tarball" "$root" "$user" "$entrypoint"
  rm -rf "$root"
}

base() {
  command -v buildah >/dev/null || { cluster_log "buildah not found (tests/install-tools.sh installs it)"; exit 2; }
  local bin key dir src
  bin=$("$here/build.sh")
  key=$(cat "$here/versions.sh" "$here/images.sh" "$bin/coredns" "$bin/kueue" | sha256sum | cut -c1-12)
  dir=$cache_root/images-base-$key
  if [ -f "$dir/complete" ]; then
    echo "$dir"
    return
  fi
  rm -rf "$dir.tmp"
  mkdir -p "$dir.tmp"
  src=$(cd "$here/build" && GOFLAGS=-mod=mod go list -m -f '{{.Dir}}' k8s.io/kubernetes)
  gcc -Os -Wall -Werror -static -DVERSION="${PAUSE_IMAGE##*:}-sadesim" -o "$dir.tmp/pause" "$src/build/pause/linux/pause.c"
  scratch_image "$PAUSE_IMAGE" "$dir.tmp/pause.tar" 65535:65535 '["/pause"]' "$dir.tmp/pause:/pause"
  scratch_image "$COREDNS_IMAGE" "$dir.tmp/coredns.tar" 65532:65532 '["/coredns"]' "$bin/coredns:/coredns"
  # Kueue's manager, where its Deployment runs it (/manager).
  scratch_image "$KUEUE_IMAGE" "$dir.tmp/kueue.tar" 65532:65532 '["/manager"]' "$bin/kueue:/manager"
  rm -f "$dir.tmp/pause"
  touch "$dir.tmp/complete"
  rm -rf "$dir"
  mv "$dir.tmp" "$dir"
  echo "$dir"
}

# copy_libs DIR FILE...: the shared libraries each FILE links, copied into DIR at their paths.
copy_libs() {
  local dir=$1 file lib
  shift
  for file in "$@"; do
    for lib in $(ldd "$file" 2>/dev/null | awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }'); do
      mkdir -p "$dir$(dirname "$lib")"
      cp -L "$lib" "$dir$lib"
    done
  done
}

# cc_base DIR: the rest of a distroless/cc-like root: the nonroot user, CA certificates, /tmp.
cc_base() {
  local dir=$1
  mkdir -p "$dir/etc/ssl/certs" "$dir/tmp" "$dir/home/nonroot"
  chmod 1777 "$dir/tmp"
  chown 65532:65532 "$dir/home/nonroot"
  printf 'root:x:0:0:root:/root:/sbin/nologin\nnonroot:x:65532:65532:nonroot:/home/nonroot:/sbin/nologin\n' >"$dir/etc/passwd"
  printf 'root:x:0:\nnonroot:x:65532:\n' >"$dir/etc/group"
  cp /etc/ssl/certs/ca-certificates.crt "$dir/etc/ssl/certs/"
}

# root_image NAME TARBALL ROOT USER ENTRYPOINT_JSON [ENV...]: an image of the folder ROOT.
root_image() {
  local name=$1 tarball=$2 root=$3 user=$4 entrypoint=$5 c e
  shift 5
  tar -C "$root" -cf "$root.tar" .
  c=$(buildah from scratch)
  buildah add "$c" "$root.tar" / >/dev/null
  for e in "$@"; do buildah config --env "$e" "$c"; done
  buildah config --user "$user" --entrypoint "$entrypoint" "$c"
  buildah commit --rm --quiet "$c" "$name" >/dev/null
  rm -f "$tarball" "$root.tar"
  buildah push --quiet "$name" "docker-archive:$tarball:$name"
  buildah rmi "$name" >/dev/null
}

product() {
  local tag=$1 out=$2 target work b file
  command -v buildah >/dev/null || { cluster_log "buildah not found (tests/install-tools.sh installs it)"; exit 2; }
  target=$(cd "$here/../.." && realpath "${CARGO_TARGET_DIR:-target}")/debug
  for b in sadesim-operator sim-worker sadesim; do
    [ -x "$target/$b" ] || { cluster_log "$target/$b missing: cargo build --workspace first"; exit 2; }
  done
  mkdir -p "$out"
  work=$(mktemp -d)
  for b in sadesim-operator sim-worker sadesim; do
    mkdir -p "$work/bin"
    objcopy --strip-debug "$target/$b" "$work/bin/$b"
  done

  mkdir -p "$work/operator/usr/local/bin"
  cp "$work/bin/sadesim-operator" "$work/operator/usr/local/bin/"
  copy_libs "$work/operator" "$work/bin/sadesim-operator"
  cc_base "$work/operator"
  root_image "ghcr.io/sadesim/sadesim:$tag" "$out/operator.tar" "$work/operator" 65532:65532 \
    '["/usr/local/bin/sadesim-operator"]'

  mkdir -p "$work/worker/usr/local/bin"
  cp "$work/bin/sim-worker" "$work/bin/sadesim" "$work/worker/usr/local/bin/"
  copy_libs "$work/worker" "$work/bin/sim-worker" "$work/bin/sadesim"
  cc_base "$work/worker"
  root_image "ghcr.io/sadesim/sim-worker:$tag" "$out/sim-worker.tar" "$work/worker" 65532:65532 \
    '["/usr/local/bin/sim-worker"]'

  # The camera image: the worker's root plus lavapipe (mesa-vulkan-drivers) and the Vulkan
  # loader (libvulkan1) with everything they link.
  cp -a "$work/worker" "$work/camera"
  local lavapipe=/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so icd=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json
  [ -f "$lavapipe" ] && [ -f "$icd" ] || { cluster_log "lavapipe missing (mesa-vulkan-drivers)"; exit 2; }
  for file in /usr/lib/x86_64-linux-gnu/libvulkan.so.1 "$lavapipe" "$icd"; do
    mkdir -p "$work/camera$(dirname "$file")"
    cp -L "$file" "$work/camera$file"
  done
  copy_libs "$work/camera" /usr/lib/x86_64-linux-gnu/libvulkan.so.1 "$lavapipe"
  root_image "ghcr.io/sadesim/sim-worker-camera:$tag" "$out/sim-worker-camera.tar" "$work/camera" 65532:65532 \
    '["/usr/local/bin/sim-worker"]' HOME=/tmp XDG_CACHE_HOME=/tmp/.cache

  # busybox for tests/e2e/pilot-exit.yaml's pilot.
  [ -x /bin/busybox ] || { cluster_log "/bin/busybox missing (busybox-static)"; exit 2; }
  mkdir -p "$work/busybox/bin"
  cp /bin/busybox "$work/busybox/bin/"
  for b in sh sleep echo cat ls true false; do ln -s busybox "$work/busybox/bin/$b"; done
  cc_base "$work/busybox"
  root_image docker.io/library/busybox:1.36 "$out/busybox.tar" "$work/busybox" 0:0 '["/bin/sh"]' PATH=/bin
  rm -rf "$work"
}

import() {
  local tarball
  for tarball in "$1"/*.tar; do
    ctr --address "$CONTAINERD_SOCKET" -n k8s.io images import "$tarball" >/dev/null
  done
}

case "${1:-}" in
  base) base ;;
  product) product "$2" "$3" ;;
  import) import "$2" ;;
  *) echo "usage: $0 base | product TAG DIR | import DIR" >&2; exit 2 ;;
esac
