#!/usr/bin/env bash
# Runs every cargo-fuzz target of fuzz/ for a fixed budget, one after the other, one job each
# (docs/fuzzing.md):
#
#   scripts/fuzz.sh                 # 600 s of each target
#   FUZZ_SECONDS=120 scripts/fuzz.sh expr dat
#
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz --locked`). Builds the
# targets once (release, debug assertions and overflow checks on, no sanitizer: safe Rust),
# into fuzz/target. Each target runs on a scratch copy of its corpus (fuzz/corpus/TARGET, which
# the suite replays in tests/fuzz_corpus.rs), with libFuzzer's limits: 10 s per input, 2 GiB of
# memory. What it adds is merged back minimised (`-merge=1`: only inputs that reach new
# coverage), so the kept corpus stays small. A crash, timeout or memory blow-up stops the
# target and leaves the input in fuzz/artifacts/TARGET/; the script goes on with the next target
# and exits 1 at the end. Prints, per target, the CPU seconds it used (user + system, from
# /usr/bin/time) and libFuzzer's last status line.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"

seconds=${FUZZ_SECONDS:-600}
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(spec_json spec_toml expr checkpoint dat http_spec)
fi

if [ -z "${FUZZ_NO_BUILD:-}" ]; then # FUZZ_NO_BUILD=1: the targets are built already
    cargo +nightly fuzz build -s none --debug-assertions
fi
bin=target/x86_64-unknown-linux-gnu/release

failed=0
for t in "${targets[@]}"; do
    scratch=$(mktemp -d)
    cp -r "corpus/$t/." "$scratch/"
    mkdir -p "artifacts/$t"
    log=$(mktemp)
    set +e
    /usr/bin/time -f "%U %S" -o "$log.time" "$bin/$t" -jobs=1 -workers=1 \
        -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
        -artifact_prefix="artifacts/$t/" -print_final_stats=1 "$scratch" >"$log" 2>&1
    status=$?
    set -e
    # With -jobs, libFuzzer runs the target in a child process that writes fuzz-0.log here.
    if [ -f fuzz-0.log ]; then
        cat fuzz-0.log >>"$log"
        rm -f fuzz-0.log
    fi
    cpu=$(awk '{printf "%.0f", $1 + $2}' "$log.time")
    last=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
    echo "$t: exit $status, ${cpu} s CPU, $last"
    grep -E 'ERROR|panicked|SUMMARY|Test unit written' "$log" | head -5 || true
    if [ "$status" -ne 0 ]; then
        failed=1
    fi
    # Keep only what reaches new coverage.
    merged=$(mktemp -d)
    "$bin/$t" -merge=1 -timeout=10 -rss_limit_mb=2048 "$merged" "corpus/$t" "$scratch" \
        >/dev/null 2>&1 || true
    if [ -n "$(ls -A "$merged")" ]; then
        # The seeds and the crashes found stay under their names; the fuzzer's inputs are
        # named by their SHA-1 (a seed's own content is not copied twice).
        kept=$(find "corpus/$t" -type f \( -name 'seed-*' -o -name 'crash-*' \) -exec sha1sum {} + | cut -d' ' -f1)
        find "corpus/$t" -type f ! -name 'seed-*' ! -name 'crash-*' -delete
        for f in "$merged"/*; do
            name=$(basename "$f")
            if ! grep -qx "$name" <<<"$kept"; then
                cp "$f" "corpus/$t/$name"
            fi
        done
    fi
    rm -rf "$scratch" "$merged" "$log" "$log.time"
done
exit $failed
