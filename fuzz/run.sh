#!/usr/bin/env bash
# Fuzzes every reader in turn: `fuzz/run.sh [SECONDS_PER_TARGET] [TARGET…]` (default 60 s, all
# targets). Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
#
# New inputs that reach new code are added to fuzz/corpus/TARGET; a crash is written to
# fuzz/artifacts/TARGET and stops that target. A crash, once fixed, belongs in
# fuzz/regressions/TARGET so the test suite replays it (crates/isocube-io/tests/fuzz_corpus.rs).
# Prints one line per target: executions, seconds, corpus size, crashes.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-60}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(cargo +nightly fuzz list)
fi
cargo +nightly fuzz build -O >/dev/null 2>&1 || cargo +nightly fuzz build -O
mkdir -p logs
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    # -malloc_limit_mb: one allocation over 256 MiB is a crash, since the harness caps volume
    # reads at 64 MiB (harness.rs). -max_len: inputs up to 16 KiB (the seeds are under 8 KiB).
    status=ok
    cargo +nightly fuzz run -O "$t" -- \
        -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=256 \
        -max_len=16384 -timeout=10 -print_final_stats=1 \
        >"logs/$t.log" 2>&1 || status=CRASH
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "logs/$t.log" | grep -o '[0-9]*$' || echo '?')
    secs=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "logs/$t.log" | grep -o '[0-9]*$' || echo '?')
    printf '%-14s %s executions (%s/s), corpus %s, %s\n' "$t" "$execs" "$secs" \
        "$(ls "corpus/$t" | wc -l)" "$status"
done
