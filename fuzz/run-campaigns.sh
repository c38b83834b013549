#!/usr/bin/env bash
# Runs every fuzz target for SECONDS (default 600) each, one after the other, from seed corpora
# made of the repository's own fixtures, and prints one Markdown table row per target:
# executions, corpus size, and crashes found (crash files are left in fuzz/artifacts/TARGET/).
# Needs cargo-fuzz (`cargo install cargo-fuzz`); on a stable toolchain RUSTC_BOOTSTRAP=1 lets it
# pass its nightly flags, and `-s none` skips AddressSanitizer (safe Rust: the targets look for
# panics, hangs and memory blow-ups, which libFuzzer reports without it).
#
#   fuzz/run-campaigns.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(detect calibration rig scene scenario inputs y4m image)
export RUSTC_BOOTSTRAP=1

# Seed corpora: the checked-in files each parser reads (the YAML/JSON bodies take a first byte
# that selects JSON when odd, so each seed gets one).
seed() { # target file json-byte
    mkdir -p "corpus/$1"
    if [ -n "${3:-}" ]; then
        { printf "\\x$3"; cat "$2"; } > "corpus/$1/seed-$(basename "$2")"
    else
        cp "$2" "corpus/$1/seed-$(basename "$2")"
    fi
}
for f in ../fixtures/calibration/*.yaml; do seed calibration "$f"; done
for f in ../fixtures/rigs/*.yaml; do seed rig "$f" 00; done
for f in ../fixtures/rigs/*.json; do seed rig "$f" 01; done
for f in ../fixtures/scenes/*.yaml; do seed scene "$f" 00; done
for f in ../fixtures/scenes/*.json; do seed scene "$f" 01; done
for f in ../fixtures/scenarios/*.yaml; do seed scenario "$f" 00; done
mkdir -p corpus/inputs corpus/y4m corpus/image corpus/detect
printf 'frame,v2,w2,pan\n0,0.0,0.0,0.0\n1,0.35,0.02,0.1\n' > corpus/inputs/seed-frames.csv
printf 't,w2,v2\n0.0,0.1,0.5\n0.5,0.0,0.6\n' > corpus/inputs/seed-times.csv
{ printf 'YUV4MPEG2 W4 H2 F30:1 Cmono\nFRAME\n'; printf '\x10\x20\x30\x40\x50\x60\x70\x80'; } > corpus/y4m/seed-mono.y4m
{ printf 'YUV4MPEG2 W2 H2 F30000:1001 C420jpeg\nFRAME\n'; printf '\x10\x20\x30\x40\x80\x80'; } > corpus/y4m/seed-420.y4m
for f in ../crates/formation-sim/assets/*.png ../docs/img/*.png; do
    [ -f "$f" ] && [ "$(stat -c %s "$f")" -lt 200000 ] && cp "$f" corpus/image/ || true
done

cargo fuzz build -s none >/dev/null
echo "| target | seconds | executions | corpus | crashes |"
echo "|---|---:|---:|---:|---:|"
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    log="artifacts/$t/campaign.log"
    set +e
    cargo fuzz run -s none "$t" "corpus/$t" -- -max_total_time="$secs" -rss_limit_mb=2048 \
        -timeout=10 -print_final_stats=1 > "$log" 2>&1
    set -e
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
    corpus=$(find "corpus/$t" -type f | wc -l)
    crashes=$(find "artifacts/$t" -type f \( -name 'crash-*' -o -name 'oom-*' -o -name 'timeout-*' \) | wc -l)
    echo "| $t | $secs | ${runs:-?} | $corpus | $crashes |"
done
