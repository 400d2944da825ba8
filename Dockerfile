# The autopilot in a small image, for campaigns of `autopilot batch` on a cluster
# (docs/campaigns.md). Built from the repository's root:
#   docker build -t autopilot --build-arg AUTOPILOT_GIT_HASH=$(git rev-parse HEAD) .
# The git commit goes into every shard's manifest: `autopilot batch merge` refuses shards of two
# builds.

# Build stage: the release binary, nothing else.
FROM rust:1-slim-bookworm AS build
WORKDIR /src
COPY . .
ARG AUTOPILOT_GIT_HASH=unknown
ENV AUTOPILOT_GIT_HASH=${AUTOPILOT_GIT_HASH}
RUN cargo build --release --locked -p autopilot --bin autopilot

# Final stage: the binary and the parameter files (airframes, flight.toml), run as a user.
FROM debian:bookworm-slim
COPY --from=build /src/target/release/autopilot /usr/local/bin/autopilot
COPY params /opt/autopilot/params
WORKDIR /opt/autopilot
USER 65532:65532
ENTRYPOINT ["/usr/local/bin/autopilot"]
CMD ["--help"]
