#!/usr/bin/env bash
# Coverage-guided fuzzing of every reader with AFL++ (cargo afl), one reader after another.
#
#   fuzz/run-afl.sh [SECONDS_PER_READER] [READER…]
#
# Builds the instrumented target (cargo afl build --release), then runs `cargo afl fuzz` on each
# reader for SECONDS_PER_READER (default 600) starting from its seed corpus, and prints the
# inputs tried (execs_done), the crashes and the hangs AFL saved. Findings are in
# fuzz/out/<reader>/default/{crashes,hangs}/; replay one with
#   fuzz/target/release/readers <reader> < fuzz/out/<reader>/default/crashes/<file>
# A run resumes where the previous one stopped when fuzz/out/<reader> exists (AFL_AUTORESUME).
set -euo pipefail
cd "$(dirname "$0")"
seconds="${1:-600}"
shift || true
readers=("$@")
if [ ${#readers[@]} -eq 0 ]; then
    readers=(ply obj scene-toml scene-json scene-xml dataset reference exr model optimize-checkpoint
             train-checkpoint samples tables son24-bin colmap-cameras-txt colmap-images-txt
             colmap-cameras-bin colmap-images-bin transforms-json photo)
fi
cargo afl build --release
export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1 AFL_AUTORESUME=1
for r in "${readers[@]}"; do
    corpus="corpus/$r"
    [ "$r" = tables ] && corpus="../crates/tables/data"
    mkdir -p "out/$r"
    cargo afl fuzz -i "$corpus" -o "out/$r" -t 2000 -m none -V "$seconds" \
        -- target/release/readers "$r" > "out/$r/afl.log" 2>&1 || true
    stats="out/$r/default/fuzzer_stats"
    printf '%-20s execs_done %10s  crashes %s  hangs %s  corpus %s\n' "$r" \
        "$(awk -F' *: ' '$1=="execs_done"{print $2}' "$stats")" \
        "$(awk -F' *: ' '$1=="saved_crashes"{print $2}' "$stats")" \
        "$(awk -F' *: ' '$1=="saved_hangs"{print $2}' "$stats")" \
        "$(awk -F' *: ' '$1=="corpus_count"{print $2}' "$stats")"
done
