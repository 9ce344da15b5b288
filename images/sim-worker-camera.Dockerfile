# syntax=docker/dockerfile:1
# The worker image with Vulkan: the coordinator of a run with onboard cameras
# (`spec.fleet[].cameras`) uses it (the operator's `--camera-image`, Helm value
# `cameraImage`), because that pod renders every camera frame through wgpu on Vulkan
# (docs/view.md, "Onboard cameras"). Every other pod keeps the small distroless worker image
# (images/sim-worker.Dockerfile): Mesa and LLVM (about 120 MB installed) would only weigh on
# every pull.
#
# Vulkan drivers in this image:
# - Mesa's `mesa-vulkan-drivers`: lavapipe (Vulkan 1.3 on the CPU, always there), and
#   radv/anv for AMD and Intel GPUs the pod is given;
# - on NVIDIA GPU nodes the NVIDIA container runtime mounts the driver's own Vulkan ICD
#   (the operator sets NVIDIA_DRIVER_CAPABILITIES=graphics,utility when
#   `spec.rendering.gpus` is set). wgpu prefers a GPU adapter over lavapipe; the
#   coordinator's log names the adapter it rendered on.
#
# Build from the repository root:
#   docker build -f images/sim-worker-camera.Dockerfile -t ghcr.io/sadesim/sim-worker-camera:0.1.0 .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p sim-worker -p sadesim \
 && install -D -m 0755 -t /out target/release/sim-worker target/release/sadesim

FROM debian:bookworm-slim
# Versions are Debian 12's (Mesa 22.3, the Vulkan loader 1.3.239, as on the machine the
# camera tests run on); exact pins would break the build when Debian replaces a version
# with its security update.
# hadolint ignore=DL3008
RUN apt-get update \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
      mesa-vulkan-drivers libvulkan1 ca-certificates \
 && rm -rf /var/lib/apt/lists/*
COPY --from=build /out/sim-worker /out/sadesim /usr/local/bin/
# The root is read-only: Mesa's shader cache and anything else that wants a home go to the
# pod's writable /tmp emptyDir.
ENV HOME=/tmp XDG_CACHE_HOME=/tmp/.cache
# The same non-root user as the distroless image's `nonroot`; pods set runAsUser 65532.
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sim-worker"]
