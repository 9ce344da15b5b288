# syntax=docker/dockerfile:1
# The `sadesim-operator` binary: the Kubernetes operator alone (crate `operator/`), which
# links no simulation engine; the Helm chart runs it. (`sadesim operator` is the same
# operator inside the full CLI.)
#
# Runtime: distroless `nonroot` (glibc, CA certificates for the API server and object
# stores; no shell, no package manager).
#
# Build from the repository root:
#   docker build -f images/operator.Dockerfile -t ghcr.io/sadesim/sadesim:0.1.0 .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p sadesim-operator \
 && install -D -m 0755 -t /out target/release/sadesim-operator

FROM gcr.io/distroless/cc-debian12:nonroot
COPY --from=build /out/sadesim-operator /usr/local/bin/sadesim-operator
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sadesim-operator"]
