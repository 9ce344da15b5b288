# syntax=docker/dockerfile:1
# The Chicago case-study pilot (examples/pilots/chicago, Rust): the image
# examples/chicago-museum*.yaml name in `spec.pilot.image`. Its entrypoint is the pilot; the
# scenarios' `containerCommand` adds the variant's flags. It reads the fleet file
# (SADESIM_FLEET) and the scenario (SADESIM_SCENARIO) the operator mounts.
#
# Build from the repository root:
#   docker build -f images/pilot-chicago.Dockerfile -t ghcr.io/sadesim/pilot-chicago:0.1.0 .
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked -p chicago-pilot \
 && install -D -m 0755 -t /out target/release/chicago-pilot

FROM gcr.io/distroless/cc-debian12:nonroot
COPY --from=build /out/chicago-pilot /usr/local/bin/
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/chicago-pilot"]
