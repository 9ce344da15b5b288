# syntax=docker/dockerfile:1
# The worker image with OpenFOAM: the `<run>-assets` Job of a run whose
# `environment.wind.urban.model` is `openfoam` uses it (the operator's `--openfoam-image`,
# Helm value `openfoamImage`), because that Job runs blockMesh, snappyHexMesh, simpleFoam and
# postProcess over the world's buildings (docs/wind-cfd.md). Every other pod keeps the small
# distroless worker image (images/sim-worker.Dockerfile): OpenFOAM (Debian's `openfoam` and
# `libopenfoam`, 410 MB installed) and its MPI would only weigh on every pull.
#
# Debian bookworm's `openfoam` is v1912, the version the cube reference and the Helsinki
# cross-check were computed with; the binaries are built on bookworm too, so they find the
# same glibc at run time.
#
# Build from the repository root:
#   docker build -f images/sim-worker-openfoam.Dockerfile -t ghcr.io/sadesim/sim-worker-openfoam:0.1.0 .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p sim-worker -p sadesim \
 && install -D -m 0755 -t /out target/release/sim-worker target/release/sadesim

FROM debian:bookworm-slim
# Debian 12's openfoam is v1912 (see above); exact version pins would break the build when
# Debian replaces a version with its security update.
# hadolint ignore=DL3008
RUN apt-get update \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends openfoam ca-certificates \
 && rm -rf /var/lib/apt/lists/*
COPY --from=build /out/sim-worker /out/sadesim /usr/local/bin/
# OpenFOAM reads its own data from WM_PROJECT_DIR (Debian's path, also sim-worker's
# default); HOME points at the writable /tmp emptyDir because the root is read-only and
# OpenFOAM looks for user settings under $HOME/.OpenFOAM.
ENV WM_PROJECT_DIR=/usr/share/openfoam HOME=/tmp
# The same non-root user as the distroless image's `nonroot`; pods set runAsUser 65532.
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sim-worker"]
