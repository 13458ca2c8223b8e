#!/usr/bin/env bash
# The test command of README.md, and what CI (.ci/run) runs on a clean checkout.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo --version
scripts/check_core_purity.sh
# The PostgreSQL store's tests (tests/service_postgres*.rs) start a private server from the
# distribution's binaries: install them when missing (as root, e.g. CI on a fresh machine).
if ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        DEBIAN_FRONTEND=noninteractive apt-get update -q
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q postgresql
    else
        echo "PostgreSQL is missing: install the postgresql package (apt-get install -y postgresql)" >&2
        exit 1
    fi
fi
cargo test --workspace
# The Python client (clients/python), installed as a user would, against the binary just built.
python3 -m pip install --quiet --disable-pip-version-check --root-user-action=ignore "./clients/python[test]"
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
SIGNORINI_BIN="$target_dir/debug/signorini" python3 -m pytest -q -p no:cacheprovider clients/python
