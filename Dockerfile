# Build: docker build -t landform .   Run: docker run -p 8080:8080 -v landform-data:/data landform
FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY benches ./benches
# Embedded in the binary at compile time (refinery's PostgreSQL migrations).
COPY migrations ./migrations
# The playground's built bundle (committed; no Node in the image), embedded by rust-embed.
COPY web/dist ./web/dist
# The examples, served as presets (GET /v1/presets), embedded by rust-embed.
COPY api ./api
# The load generator is a workspace member: its manifest and sources must be there for Cargo to
# read the workspace, though only the service is built.
COPY loadtests/Cargo.toml ./loadtests/Cargo.toml
COPY loadtests/src ./loadtests/src
# So is the Rust client (and a dev-dependency of the service's tests).
COPY clients/rust/Cargo.toml ./clients/rust/Cargo.toml
COPY clients/rust/src ./clients/rust/src
RUN cargo build --locked --release --bin landform

FROM debian:bookworm-slim
# CA certificates: an S3 artifact store (--artifact-store s3://…) is reached over TLS.
RUN apt-get update && apt-get install -y --no-install-recommends ca-certificates && rm -rf /var/lib/apt/lists/*
RUN useradd --system --uid 10001 --home /data landform && mkdir -p /data && chown landform /data
COPY --from=build /src/target/release/landform /usr/local/bin/landform
USER landform
WORKDIR /data
ENV LANDFORM_ADDR=0.0.0.0:8080 LANDFORM_DATABASE=/data/landform.db RUST_LOG=info
EXPOSE 8080
HEALTHCHECK --interval=30s --timeout=3s CMD ["bash", "-c", "exec 3<>/dev/tcp/127.0.0.1/8080 && printf 'GET /healthz HTTP/1.0\\r\\n\\r\\n' >&3 && grep -q ok <&3"]
ENTRYPOINT ["landform"]
CMD ["serve"]
