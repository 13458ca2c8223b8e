#!/usr/bin/env bash
# The test command of README.md, and what CI (.ci/run) runs on a clean checkout.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo --version
scripts/check_core_purity.sh
cargo test --workspace
