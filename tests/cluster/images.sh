#!/usr/bin/env bash
# Container images of the test cluster, built here (no registry is reachable) with buildah
# and kept as docker-archive tarballs in a cache outside the clone.
#
#   tests/cluster/images.sh base          # the pause (pod sandbox) and CoreDNS images; prints their folder
#   tests/cluster/images.sh product TAG DIR  # the project's images, tagged TAG, into DIR
#   tests/cluster/images.sh import DIR [IMAGE...]  # DIR's tarballs (or those of IMAGEs) into the cluster's containerd
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
# them. The OpenFOAM worker image and the example pilots' image need a distribution: their
# base is a Debian 12 root made here with mmdebstrap from Debian's archive (Debian's openfoam;
# Debian's Python 3.11 with the pilots' pinned wheels from PyPI), cached outside the clone, as
# images/sim-worker-openfoam.Dockerfile and images/pilot-*.Dockerfile install them on
# debian:bookworm-slim and python:3.11-slim-bookworm. The binaries are the workspace's dev
# build (optimised; debug info stripped), from $CARGO_TARGET_DIR (default target/).
# docker.io/library/busybox:1.36, the pilot of tests/e2e/pilot-exit.yaml, is Debian's
# busybox-static.
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
  root_image "$name" "$tarball" "$user" "$entrypoint" "$root"
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

# root_image NAME TARBALL USER ENTRYPOINT_JSON LAYERS [BUILDAH_CONFIG_ARG...]: an image of
# LAYERS (space-separated folders and tarballs, added in order), with the user, entrypoint and
# any further `buildah config` arguments (--env K=V, --workingdir DIR).
root_image() {
  local name=$1 tarball=$2 user=$3 entrypoint=$4 layers=$5 c layer
  shift 5
  c=$(buildah from scratch)
  for layer in $layers; do
    if [ -d "$layer" ]; then
      tar -C "$layer" -cf "$layer.tar" .
      buildah add "$c" "$layer.tar" / >/dev/null
      rm -f "$layer.tar"
    else
      buildah add "$c" "$layer" / >/dev/null
    fi
  done
  buildah config --user "$user" --entrypoint "$entrypoint" "$@" "$c"
  buildah commit --rm --quiet "$c" "$name" >/dev/null
  rm -f "$tarball"
  buildah push --quiet "$name" "docker-archive:$tarball:$name"
  buildah rmi "$name" >/dev/null
}

# debian_root NAME PACKAGES [REQUIREMENTS...]: prints the path of a cached tarball of a Debian 12
# root (mmdebstrap, variant essential) holding PACKAGES (comma-separated) and the Python wheels
# of the pip REQUIREMENTS files, installed into /usr/local as `pip install -r` does in
# images/pilot-python.Dockerfile. The wheels are downloaded on this machine (the project's
# .venv pip, which trusts this machine's certificates) and installed offline in the root.
# Documentation, manual pages and locales are left out, as in Debian's slim images. Keyed by
# this file, the packages and the requirements; a new key replaces the root of the old one.
debian_root() {
  local name=$1 packages=$2 key dir file
  shift 2
  command -v mmdebstrap >/dev/null || { cluster_log "mmdebstrap not found (tests/install-tools.sh installs it)"; exit 2; }
  key=$(cat "$here/images.sh" "$@" <(echo "$packages") | sha256sum | cut -c1-12)
  dir=$cache_root/debian-$name-$key
  if [ ! -f "$dir/root.tar" ]; then
    cluster_log "building the Debian 12 root $name ($packages)"
    rm -rf "$dir.tmp"
    mkdir -p "$dir.tmp/wheels"
    local hooks=()
    if [ "$#" -gt 0 ]; then
      local req=()
      for file in "$@"; do req+=(-r "$file"); done
      "$here/../../.venv/bin/python" -m pip download --quiet --disable-pip-version-check --only-binary=:all: \
        --python-version 3.11 --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
        --platform manylinux2014_x86_64 --implementation cp -d "$dir.tmp/wheels" "${req[@]}"
      # shellcheck disable=SC2016  # $1 is mmdebstrap's root, expanded by the hook's shell
      hooks+=(--customize-hook="copy-in $dir.tmp/wheels /tmp"
        --customize-hook='chroot "$1" sh -c "python3 -m pip install --quiet --no-index --no-cache-dir --disable-pip-version-check --break-system-packages --root-user-action=ignore /tmp/wheels/*.whl && rm -rf /tmp/wheels"')
    fi
    mmdebstrap --quiet --mode=root --variant=essential --include="$packages" \
      --dpkgopt='path-exclude=/usr/share/doc/*' --dpkgopt='path-exclude=/usr/share/man/*' \
      --dpkgopt='path-exclude=/usr/share/locale/*' --dpkgopt='path-exclude=/usr/share/info/*' \
      "${hooks[@]}" bookworm "$dir.tmp/root.tar" http://deb.debian.org/debian
    rm -rf "$dir.tmp/wheels" "$dir"
    mv "$dir.tmp" "$dir"
    # Roots of this name with another key are out of date: they go (each is hundreds of MB).
    find "$cache_root" -maxdepth 1 -name "debian-$name-*" ! -path "$dir" -exec rm -rf {} +
  fi
  echo "$dir/root.tar"
}

product() {
  local tag=$1 out=$2 target work b file
  command -v buildah >/dev/null || { cluster_log "buildah not found (tests/install-tools.sh installs it)"; exit 2; }
  target=$(cd "$here/../.." && realpath "${CARGO_TARGET_DIR:-target}")/debug
  for b in sadesim-operator sim-worker sadesim chicago-pilot; do
    [ -x "$target/$b" ] || { cluster_log "$target/$b missing: cargo build --workspace first"; exit 2; }
  done
  mkdir -p "$out"
  work=$(mktemp -d)
  for b in sadesim-operator sim-worker sadesim chicago-pilot; do
    mkdir -p "$work/bin"
    objcopy --strip-debug "$target/$b" "$work/bin/$b"
  done

  mkdir -p "$work/operator/usr/local/bin"
  cp "$work/bin/sadesim-operator" "$work/operator/usr/local/bin/"
  copy_libs "$work/operator" "$work/bin/sadesim-operator"
  cc_base "$work/operator"
  root_image "ghcr.io/sadesim/sadesim:$tag" "$out/operator.tar" 65532:65532 \
    '["/usr/local/bin/sadesim-operator"]' "$work/operator"

  # The worker's binaries alone (also the top layer of the OpenFOAM image), then on the
  # distroless-like base.
  mkdir -p "$work/worker-bin/usr/local/bin"
  cp "$work/bin/sim-worker" "$work/bin/sadesim" "$work/worker-bin/usr/local/bin/"
  cp -a "$work/worker-bin" "$work/worker"
  copy_libs "$work/worker" "$work/bin/sim-worker" "$work/bin/sadesim"
  cc_base "$work/worker"
  root_image "ghcr.io/sadesim/sim-worker:$tag" "$out/sim-worker.tar" 65532:65532 \
    '["/usr/local/bin/sim-worker"]' "$work/worker"

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
  root_image "ghcr.io/sadesim/sim-worker-camera:$tag" "$out/sim-worker-camera.tar" 65532:65532 \
    '["/usr/local/bin/sim-worker"]' "$work/camera" --env HOME=/tmp --env XDG_CACHE_HOME=/tmp/.cache

  # The OpenFOAM image (images/sim-worker-openfoam.Dockerfile): the worker's binaries on a
  # Debian 12 root with Debian's openfoam. The binaries are built on this Debian 12 machine,
  # so they find the same glibc there.
  root_image "ghcr.io/sadesim/sim-worker-openfoam:$tag" "$out/sim-worker-openfoam.tar" 65532:65532 \
    '["/usr/local/bin/sim-worker"]' "$(debian_root openfoam openfoam,ca-certificates) $work/worker-bin" \
    --env WM_PROJECT_DIR=/usr/share/openfoam --env HOME=/tmp

  # The example pilots (images/pilot-examples.Dockerfile on images/pilot-python.Dockerfile):
  # Debian 12's Python 3.11 with both requirement files' wheels, the scripts in /pilot/pilots.
  # The examples name it with the tag 0.1.0, whatever TAG is.
  mkdir -p "$work/pilots/pilot/pilots"
  cp "$here"/../../examples/pilots/*.py "$work/pilots/pilot/pilots/"
  root_image ghcr.io/sadesim/pilot-examples:0.1.0 "$out/pilot-examples.tar" 65532:65532 '["python3"]' \
    "$(debian_root python python3,python3-pip,ca-certificates "$here/../../images/pilot-python.requirements.txt" \
      "$here/../../images/pilot-examples.requirements.txt") $work/pilots" \
    --env PYTHONDONTWRITEBYTECODE=1 --env PYTHONUNBUFFERED=1 --env HOME=/tmp --workingdir /pilot

  # The Chicago case study's pilot (images/pilot-chicago.Dockerfile), also tagged 0.1.0 as
  # examples/chicago-museum*.yaml name it.
  mkdir -p "$work/chicago/usr/local/bin"
  cp "$work/bin/chicago-pilot" "$work/chicago/usr/local/bin/"
  copy_libs "$work/chicago" "$work/bin/chicago-pilot"
  cc_base "$work/chicago"
  root_image ghcr.io/sadesim/pilot-chicago:0.1.0 "$out/pilot-chicago.tar" 65532:65532 \
    '["/usr/local/bin/chicago-pilot"]' "$work/chicago"

  # busybox for tests/e2e/pilot-exit.yaml's pilot.
  [ -x /bin/busybox ] || { cluster_log "/bin/busybox missing (busybox-static)"; exit 2; }
  mkdir -p "$work/busybox/bin"
  cp /bin/busybox "$work/busybox/bin/"
  for b in sh sleep echo cat ls true false; do ln -s busybox "$work/busybox/bin/$b"; done
  cc_base "$work/busybox"
  root_image docker.io/library/busybox:1.36 "$out/busybox.tar" 0:0 '["/bin/sh"]' "$work/busybox" --env PATH=/bin
  rm -rf "$work"
}

# import_images DIR [IMAGE...]: DIR's image tarballs into the cluster's containerd (k8s.io namespace);
# with IMAGEs, only the tarballs holding one of them (by the tag in the tarball's manifest).
import_images() {
  local dir=$1 tarball tags image wanted
  shift
  for tarball in "$dir"/*.tar; do
    wanted=$(($# == 0))
    tags=$(tar -xOf "$tarball" manifest.json)
    for image in "$@"; do
      case "$tags" in *"\"$image\""*) wanted=1 ;; esac
    done
    [ "$wanted" = 1 ] || continue
    ctr --address "$CONTAINERD_SOCKET" -n k8s.io images import "$tarball" >/dev/null
  done
}

case "${1:-}" in
  base) base ;;
  product) product "$2" "$3" ;;
  import) shift; import_images "$@" ;;
  *) echo "usage: $0 base | product TAG DIR | import DIR [IMAGE...]" >&2; exit 2 ;;
esac
