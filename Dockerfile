# Signorini service image: multi-stage build with a dependency-caching layer, slim non-root runtime.
# No system protoc is needed (build.rs compiles the .proto files with protox).
#   docker build -t signorini .
#   docker run -p 50051:50051 -p 8080:8080 -p 7447:7447 signorini
# The base images are build arguments: the defaults are the official images; where no registry is
# reachable, scripts/container/build-local-bases.sh makes local stand-ins and
# scripts/container/smoke.sh passes them (see docs/ci.md).
ARG RUST_IMAGE=rust:1.95-slim-bookworm
ARG RUNTIME_IMAGE=debian:bookworm-slim
FROM ${RUST_IMAGE} AS build
WORKDIR /src
# 1. Dependencies only: manifests and stub sources, so this layer is reused until Cargo.lock changes.
COPY Cargo.toml Cargo.lock ./
COPY crates/signorini-core/Cargo.toml crates/signorini-core/Cargo.toml
COPY crates/signorini-figures/Cargo.toml crates/signorini-figures/Cargo.toml
RUN mkdir -p src benches crates/signorini-core/src crates/signorini-core/benches crates/signorini-figures/src \
 && echo 'fn main() {}' > src/main.rs && touch src/lib.rs \
 && echo 'fn main() {}' > benches/service.rs \
 && touch crates/signorini-core/src/lib.rs crates/signorini-figures/src/lib.rs \
 && for b in $(sed -n 's/^name = "\(.*\)"/\1/p' crates/signorini-core/Cargo.toml | tail -n +2); do echo 'fn main() {}' > crates/signorini-core/benches/$b.rs; done \
 && printf 'fn main() {}\n' > build.rs \
 && cargo build --release --locked --bin signorini || true
# 2. The real sources.
COPY . .
RUN touch src/main.rs src/lib.rs crates/signorini-core/src/lib.rs crates/signorini-figures/src/lib.rs build.rs \
 && cargo build --release --locked --bin signorini \
 && install -D target/release/signorini /out/signorini

FROM ${RUNTIME_IMAGE}
LABEL org.opencontainers.image.title="signorini" \
      org.opencontainers.image.description="Nonsmooth contact dynamics as a service: gRPC + HTTP API, live zenoh streams" \
      org.opencontainers.image.licenses="Apache-2.0" \
      org.opencontainers.image.source="https://example.invalid/signorini"
RUN useradd --system --uid 10001 --home-dir /var/lib/signorini --create-home signorini
COPY --from=build /out/signorini /usr/local/bin/signorini
USER 10001
WORKDIR /var/lib/signorini
# gRPC, HTTP (API, /healthz, /metrics, live page), zenoh peer
EXPOSE 50051 8080 7447
ENV SIGNORINI_GRPC_ADDR=0.0.0.0:50051 \
    SIGNORINI_HTTP_ADDR=0.0.0.0:8080 \
    SIGNORINI_STORE=/var/lib/signorini/signorini.db \
    SIGNORINI_ZENOH_LISTEN=tcp/0.0.0.0:7447
VOLUME ["/var/lib/signorini"]
ENTRYPOINT ["signorini"]
CMD ["serve"]
