# syntax=docker/dockerfile:1
# The worker image every run's pods use: `sim-worker` (assets, shard, coordinator, router,
# renderer roles) and `sadesim`, which the coordinator pod runs after the coordinator to
# upload the run folder (`sadesim archive put`).
#
# The runtime is distroless (glibc, CA certificates, no package manager) in its
# `debug-nonroot` flavour, whose only addition is a static busybox at /busybox: the
# coordinator pod's entrypoint is a short /busybox/sh script that runs the coordinator, then
# the upload, whatever the coordinator's exit status (docs/kubernetes.md, "Archive").
#
# Build from the repository root:
#   docker build -f images/sim-worker.Dockerfile -t ghcr.io/sadesim/sim-worker:0.1.0 .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
# Cache mounts keep the registry and the build between image builds; the binaries are
# copied out in the same step because the target folder is not part of the layer.
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p sim-worker -p sadesim \
 && install -D -m 0755 -t /out target/release/sim-worker target/release/sadesim

FROM gcr.io/distroless/cc-debian12:debug-nonroot
COPY --from=build /out/sim-worker /out/sadesim /usr/local/bin/
# 65532 = distroless `nonroot`; pods also set runAsUser 65532 and a read-only root.
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sim-worker"]
