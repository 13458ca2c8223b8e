#!/usr/bin/env bash
# The test command of README.md, and what CI (.ci/run) runs on a clean checkout.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo --version
# System parts some tests need, installed from the distribution when missing:
# Chromium drives the pages the service serves (tests/service_browser.rs).
install_missing() { # COMMAND PACKAGE
  command -v "$1" >/dev/null 2>&1 && return
  echo "installing $2 (for $1)"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get install -y --no-install-recommends "$2" ||
    { $sudo apt-get update && $sudo apt-get install -y --no-install-recommends "$2"; }
}
[ -n "${SIGNORINI_CHROMIUM:-}" ] || install_missing chromium chromium
scripts/check_core_purity.sh
cargo test --workspace
# The Python client (clients/python), installed as a user would, against the binary just built.
python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore "./clients/python[test]"
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
SIGNORINI_BIN="$target_dir/debug/signorini" python3 -m pytest -q -p no:cacheprovider clients/python
