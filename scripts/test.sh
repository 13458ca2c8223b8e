#!/usr/bin/env bash
# The test command of README.md, and what CI (.ci/run) runs on a clean checkout.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo --version
# System parts some tests need, installed from the distribution when missing (apt-get, as root
# or through sudo): Chromium drives the pages the service serves (tests/service_browser.rs);
# PostgreSQL's binaries start the private servers of the PostgreSQL store's tests
# (tests/service_postgres*.rs); the HDF5 library is linked by the FCLib reader of `signorini
# solve` (src/problem_file/fclib.rs, through hdf5-metno), which the tests build with the optional
# feature `hdf5` (the default build, `cargo run --release`, needs no system library).
install() { # PACKAGE…
  echo "installing $* from the distribution"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get install -y -q --no-install-recommends "$@" ||
    { $sudo apt-get update -q && $sudo apt-get install -y -q --no-install-recommends "$@"; }
}
[ -n "${SIGNORINI_CHROMIUM:-}" ] || command -v chromium >/dev/null 2>&1 || install chromium
ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || install postgresql
[ -e /usr/include/hdf5/serial/hdf5.h ] || [ -e /usr/include/hdf5.h ] || install libhdf5-dev
scripts/check_core_purity.sh
cargo test --workspace --features hdf5
# The Python client (clients/python), installed as a user would, against the binary just built.
python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore "./clients/python[test]"
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
SIGNORINI_BIN="$target_dir/debug/signorini" python3 -m pytest -q -p no:cacheprovider clients/python
