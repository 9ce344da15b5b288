# The `sim-worker` binary: every runtime role (`sim-worker shard`, `sim-worker coordinator`).
# Build from the repository root:  docker build -f images/sim-worker.Dockerfile -t sim-worker .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked -p sim-worker

FROM gcr.io/distroless/cc-debian12:nonroot
COPY --from=build /src/target/release/sim-worker /usr/local/bin/sim-worker
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/sim-worker"]
