#!/usr/bin/env bash
# The numerical core (crates/signorini-core) is pure computation: no async, network, file, clock or
# printing. This check makes that a rule the build enforces, not a habit:
#  1. its normal and build dependencies contain no I/O or async crate (`cargo tree`);
#  2. its library code calls no printing, file, environment, clock or thread-count function
#     (clippy's disallowed-macros / disallowed-methods, configured in crates/signorini-core/clippy.toml).
# Tests and benches of the core may read fixtures and time themselves; only the library is checked.
set -euo pipefail
cd "$(dirname "$0")/.."

deny='^(tokio|tokio-.*|async-.*|futures.*|mio|smol|zenoh.*|tonic.*|axum.*|hyper.*|reqwest|rusqlite|libsqlite3-sys|sqlx.*|postgres.*|tokio-postgres|tracing.*|log|env_logger|tempfile|walkdir|notify|socket2|indicatif|clap)$'
found=$(cargo tree -p signorini-core -e normal,build --prefix none --format '{p}' | awk '{print $1}' | sort -u | grep -E "$deny" || true)
if [[ -n "$found" ]]; then
    echo "signorini-core depends on I/O or async crates: $found" >&2
    exit 1
fi

cargo clippy -p signorini-core --lib --quiet -- \
    -D clippy::disallowed_macros -D clippy::disallowed_methods -D clippy::disallowed_types
echo "core purity: ok (no I/O or async dependency; no printing, file, clock or environment calls)"
