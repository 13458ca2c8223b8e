#!/usr/bin/env bash
# Runs every cargo-fuzz target of fuzz/ for a fixed budget of CPU time, one after the other
# (docs/fuzzing.md):
#
#   scripts/fuzz.sh                       # 600 CPU seconds of each target
#   FUZZ_CPU_SECONDS=120 scripts/fuzz.sh expr dat
#
# The budget is CPU time (user + system of the fuzzing process, read from /proc while it runs),
# not wall time: on a machine shared with builds a wall-clock budget gives a target a fraction
# of what was asked. When the budget is spent the fuzzer gets SIGINT, prints its final stats and
# ends; FUZZ_WALL_SECONDS (default 4 × the CPU budget) bounds the wall time as well.
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz --locked`). Builds the
# targets once (release, debug assertions and overflow checks on, no sanitizer: safe Rust),
# into fuzz/target. Each target runs in one process on a scratch copy of its corpus
# (fuzz/corpus/TARGET, which the suite replays in tests/fuzz_corpus.rs), with libFuzzer's
# limits: 10 s per input, 2 GiB of memory. What it adds is merged back minimised (`-merge=1`:
# only inputs that reach new coverage), so the kept corpus stays small. A crash, timeout or
# memory blow-up stops the target and leaves the input in fuzz/artifacts/TARGET/; the script
# goes on with the next target and exits 1 at the end. Prints, per target, the CPU seconds it
# used, the wall seconds, and libFuzzer's last status line.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"

cpu_budget=${FUZZ_CPU_SECONDS:-600}
wall_budget=${FUZZ_WALL_SECONDS:-$((4 * cpu_budget))}
ticks=$(getconf CLK_TCK)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(spec_json spec_toml expr checkpoint dat fclib http_spec)
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
    start=$(date +%s)
    "$bin/$t" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
        -artifact_prefix="artifacts/$t/" -print_final_stats=1 "$scratch" >"$log" 2>&1 &
    pid=$!
    used=0
    while kill -0 "$pid" 2>/dev/null; do
        # Fields 14 and 15 of /proc/PID/stat: user and system time in clock ticks.
        used=$(awk -v t="$ticks" '{printf "%d", ($14 + $15) / t}' "/proc/$pid/stat" 2>/dev/null || echo "$used")
        if [ "$used" -ge "$cpu_budget" ] || [ $(($(date +%s) - start)) -ge "$wall_budget" ]; then
            kill -INT "$pid" 2>/dev/null || true
            break
        fi
        sleep 2
    done
    set +e
    wait "$pid"
    status=$?
    set -e
    # libFuzzer ends an interrupted run with status 72 and "run interrupted" on its log.
    if [ "$status" -eq 72 ] && grep -q 'run interrupted' "$log"; then
        status=0
    fi
    cpu=$used
    wall=$(($(date +%s) - start))
    last=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
    echo "$t: exit $status, ${cpu} s CPU, ${wall} s wall, $last"
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
        # Of the rest, the FUZZ_KEEP smallest (default 100): the whole merged corpus runs to
        # thousands of inputs and megabytes, too much for the repository.
        find "$merged" -type f -printf '%s %f\n' | sort -n | cut -d' ' -f2 |
            grep -vxF -f <(printf '%s\n' $kept) | awk -v n="${FUZZ_KEEP:-100}" 'NR <= n' |
            while read -r name; do
                cp "$merged/$name" "corpus/$t/$name"
            done
    fi
    rm -rf "$scratch" "$merged" "$log"
done
exit $failed
