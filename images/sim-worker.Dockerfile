# syntax=docker/dockerfile:1
# The worker image every run's pods use: `sim-worker` (shard, coordinator, router roles; the
# coordinator pod runs `sim-worker coordinator --finish-run`, which also writes the report and
# uploads the run folder, docs/kubernetes.md "Archive") and `sadesim` (the assets Job runs
# `sadesim assets`).
#
# The runtime is distroless (glibc, CA certificates, no package manager, no shell) in its
# `nonroot` flavour: every pod runs one program.
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

FROM gcr.io/distroless/cc-debian12:nonroot
COPY --from=build /out/sim-worker /out/sadesim /usr/local/bin/
# 65532 = distroless `nonroot`; pods also set runAsUser 65532 and a read-only root.
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sim-worker"]
