#!/usr/bin/env bash
# Builds the image and tries it as a user would, from outside the container:
#   serve in the container; submit over HTTP (curl) and over gRPC (the Python client);
#   watch the gRPC job over zenoh (Python client, eclipse-zenoh); fetch the result (curl);
#   `check` on a mounted spec; then stop and remove everything.
# With BASES=local (the default here) the base images are the local stand-ins of
# build-local-bases.sh; BASES=official builds from the Dockerfile's defaults.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
. "$here/podman.sh"
need_podman
image="${IMAGE:-localhost/signorini:smoke}"
started=$(date +%s)
step() { echo "== [$(( $(date +%s) - started )) s] $*"; }

build_args=()
if [ "${BASES:-local}" = local ]; then
    "$here/build-local-bases.sh" >/dev/null
    build_args=(--build-arg "RUST_IMAGE=$LOCAL_RUST" --build-arg "RUNTIME_IMAGE=$LOCAL_DEBIAN")
fi
# SKIP_BUILD=1 tries an image built before (IMAGE=...) without building it again.
if [ "${SKIP_BUILD:-0}" != 1 ]; then
    step "building $image"
    log="$(mktemp)"
    "${PODMAN[@]}" build "${RUN_FLAGS[@]}" "${build_args[@]}" -t "$image" "$repo" > "$log" 2>&1 \
        || { tail -30 "$log"; exit 1; }
    rm -f "$log"
fi
"${PODMAN[@]}" image inspect "$image" --format 'image size {{.Size}} bytes'

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
grpc_port=$(free_port); http_port=$(free_port); zenoh_port=$(free_port)
name="signorini-smoke-$$"
cleanup() { "${PODMAN[@]}" rm -f "$name" >/dev/null 2>&1 || true; }
trap cleanup EXIT

step "serve in the container (gRPC $grpc_port, HTTP $http_port, zenoh $zenoh_port)"
"${PODMAN[@]}" run -d --name "$name" "${RUN_FLAGS[@]}" "$image" serve \
    --grpc-addr "127.0.0.1:$grpc_port" --http-addr "127.0.0.1:$http_port" \
    --zenoh-listen "tcp/127.0.0.1:$zenoh_port" --workers 2 >/dev/null
for _ in $(seq 100); do
    curl -fsS "http://127.0.0.1:$http_port/healthz" >/dev/null 2>&1 && break
    sleep 0.2
done
curl -fsS "http://127.0.0.1:$http_port/healthz"; echo

step "submit over HTTP (curl)"
spec_json=$(python3 -c 'import json, sys, tomllib; print(json.dumps(tomllib.load(open(sys.argv[1], "rb"))))' "$repo/examples/bouncing_ball.toml")
http_job=$(curl -fsS -X POST -H 'content-type: application/json' --data "$spec_json" \
    "http://127.0.0.1:$http_port/v1/jobs" | python3 -c 'import json, sys; print(json.load(sys.stdin)["id"])')
echo "job $http_job"

step "submit over gRPC and watch over zenoh (Python client)"
python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore "$repo/clients/python[zenoh]"
python3 - "$grpc_port" "$zenoh_port" "$repo/examples/bouncing_ball.toml" <<'PY'
import sys, uuid
import numpy as np
from signorini import Client
grpc_port, zenoh_port, spec = sys.argv[1:]
with Client(f"127.0.0.1:{grpc_port}", zenoh_connect=f"tcp/127.0.0.1:{zenoh_port}") as c:
    job = f"smoke-{uuid.uuid4().hex[:8]}"
    watch = c.watch(job, via="zenoh")
    c.submit(spec, id=job)
    energy = {}
    for f in watch:
        if f.kind == "energy":
            energy.update(zip(f.step.tolist(), f.columns["energy"].tolist()))
        elif f.kind == "status":
            final = f.state
    r = c.result(job)
    stored = dict(zip(r["step"].tolist(), r["energy"].tolist()))
    same = len(energy) == len(stored) and all(energy[k] == v for k, v in stored.items())
    print(f"job {job}: {final}, {len(energy)} steps streamed over zenoh, equal to the stored result: {same}")
    assert final == "succeeded" and same
PY

step "fetch the HTTP job's result (curl)"
for _ in $(seq 100); do
    state=$(curl -fsS "http://127.0.0.1:$http_port/v1/jobs/$http_job" | python3 -c 'import json, sys; print(json.load(sys.stdin)["state"])')
    case "$state" in succeeded|failed|cancelled) break ;; esac
    sleep 0.1
done
curl -fsS "http://127.0.0.1:$http_port/v1/jobs/$http_job/result" | python3 -c '
import json, sys
r = json.load(sys.stdin)
s = r["summary"]
print("state", r["state"], "steps", s["steps"], "max |balance residual| %.3e" % s["max_abs_balance_residual"])
assert r["state"] == "succeeded"'

step "check on a mounted spec"
"${PODMAN[@]}" run --rm "${RUN_FLAGS[@]}" -v "$repo/examples:/w:ro" "$image" check /w/bouncing_ball.toml /w/chain.toml

step "stop"
"${PODMAN[@]}" stop -t 5 "$name" >/dev/null
step "smoke test passed"
