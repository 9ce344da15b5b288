# The `sadesim` binary (CLI and, with the operator issue, the Kubernetes operator).
# Build from the repository root:  docker build -f images/operator.Dockerfile -t sadesim .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked -p sadesim

FROM gcr.io/distroless/cc-debian12:nonroot
COPY --from=build /src/target/release/sadesim /usr/local/bin/sadesim
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sadesim"]
