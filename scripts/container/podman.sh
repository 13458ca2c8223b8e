# Sourced by the container scripts: the one podman invocation that works in this sandbox
# (runc, cgroupfs; crun and the default rlimits fail here), and the local base image names.
PODMAN=(podman --runtime /usr/sbin/runc --cgroup-manager cgroupfs)
RUN_FLAGS=(--network host --ulimit nofile=1024:1024 --ulimit nproc=1024:1024)
LOCAL_DEBIAN=localhost/signorini-base/debian:bookworm-slim
LOCAL_RUST=localhost/signorini-base/rust:1.95-slim-bookworm

# Installs podman, runc and mmdebstrap from the distribution when missing.
need_podman() {
    local missing=()
    command -v podman >/dev/null || missing+=(podman)
    [ -x /usr/sbin/runc ] || missing+=(runc)
    command -v mmdebstrap >/dev/null || missing+=(mmdebstrap)
    if [ ${#missing[@]} -gt 0 ]; then
        echo "installing ${missing[*]}" >&2
        apt-get install -y "${missing[@]}" >/dev/null
    fi
}
