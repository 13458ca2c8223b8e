#!/usr/bin/env bash
# Builds local stand-ins for the Dockerfile's two base images, for machines that reach no image
# registry but do reach the Debian mirror and crates.io:
#   localhost/signorini-base/debian:bookworm-slim      Debian bookworm minbase (mmdebstrap)
#   localhost/signorini-base/rust:1.95-slim-bookworm   that + gcc, libc6-dev and the host's Rust toolchain
# Then build with
#   podman build --build-arg RUST_IMAGE=localhost/signorini-base/rust:1.95-slim-bookworm \
#                --build-arg RUNTIME_IMAGE=localhost/signorini-base/debian:bookworm-slim .
# A normal Docker needs none of this: the Dockerfile's defaults are the official images.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
. "$here/podman.sh"
need_podman
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mirror="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"

if ! "${PODMAN[@]}" image exists "$LOCAL_DEBIAN"; then
    echo "== $LOCAL_DEBIAN: mmdebstrap bookworm (minbase) from $mirror"
    mmdebstrap --quiet --variant=minbase --include=ca-certificates bookworm "$work/rootfs.tar" "$mirror"
    "${PODMAN[@]}" import "$work/rootfs.tar" "$LOCAL_DEBIAN" >/dev/null
fi

if ! "${PODMAN[@]}" image exists "$LOCAL_RUST"; then
    toolchain="$(dirname "$(dirname "$(rustup which rustc)")")"
    version="$(rustc --version)"
    echo "== $LOCAL_RUST: gcc + the host's toolchain ($version, $toolchain)"
    mkdir -p "$work/ctx"
    cp -a "$toolchain" "$work/ctx/rust"
    # The host's extra certificate authorities (e.g. an egress proxy's), so cargo inside the
    # build reaches crates.io the way the host does.
    mkdir -p "$work/ctx/ca"
    cp /usr/local/share/ca-certificates/*.crt "$work/ctx/ca/" 2>/dev/null || true
    rm -rf "$work/ctx/rust/share/doc"
    cat > "$work/ctx/Containerfile" <<CF
FROM $LOCAL_DEBIAN
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev \
 && rm -rf /var/lib/apt/lists/*
COPY ca/ /usr/local/share/ca-certificates/
RUN update-ca-certificates
COPY rust /usr/local/rust
ENV CARGO_HOME=/usr/local/cargo PATH=/usr/local/rust/bin:/usr/local/cargo/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
RUN cargo --version && rustc --version
CF
    "${PODMAN[@]}" build "${RUN_FLAGS[@]}" -t "$LOCAL_RUST" "$work/ctx"
fi
"${PODMAN[@]}" images --filter reference='localhost/signorini-base/*'
