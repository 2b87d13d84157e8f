#!/usr/bin/env bash
# libFuzzer harnesses of the C core (fuzz/README.md), built with
# clang -fsanitize=fuzzer,address,undefined (UB aborts, leaks detected).
#
#   tools/fuzz.sh build [harness...]       build fuzz/build/fuzz_<harness>
#   tools/fuzz.sh smoke [harness...]       ~20 s each (FUZZ_SMOKE_SECONDS) from
#                                          the committed corpus; CI runs this
#   tools/fuzz.sh full  [harness...]       each to FUZZ_RUNS (10,000,000)
#                                          executions or FUZZ_MAX_SECONDS
#                                          (3600), whichever first; appends the
#                                          counts to fuzz/RESULTS.md
#   tools/fuzz.sh merge [harness...]       minimise the last run's findings
#                                          into fuzz/corpus/<harness>
#   tools/fuzz.sh repro HARNESS FILE...    run single inputs (reproducers)
# Harnesses: projection refine image (default: all).
# The committed corpora are only read; new inputs go to fuzz/build/work-*.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
SRC=${FUZZ_SRC:-$ROOT/cext}
OUT=$ROOT/fuzz/build
# FUZZ_TRACE_CMP=0: the core objects are built without comparison tracing
# (-fno-sanitize-coverage=trace-cmp; edge coverage, ASan and UBSan stay).
# Comparison tracing is ~60% of fuzz_refine's time; the long runs use this
# build after the corpus has been grown with tracing on (fuzz/README.md).
# It has its own build directory, fuzz/build-nocmp.
NOCMP=""
if [ "${FUZZ_TRACE_CMP:-1}" = 0 ]; then
    OUT=$ROOT/fuzz/build-nocmp
    NOCMP="-fno-sanitize-coverage=trace-cmp"
fi
ALL_HARNESSES=(projection refine image)
CC=${CC_FUZZ:-clang}
SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer -g -O1"
CFLAGS="-std=c11 -Wall -Wextra -Wno-missing-field-initializers -ffp-contract=off \
-D_POSIX_C_SOURCE=200809L -I$SRC -I$ROOT/fuzz"

# libFuzzer options per harness: input size cap and per-input timeout.
max_len() { case $1 in projection) echo 128 ;; refine) echo 768 ;; image) echo 4096 ;; esac; }
rss_limit() { echo 2048; }
ASAN_BASE="detect_leaks=1:allocator_may_return_null=1:detect_stack_use_after_return=1"
asan_options() { echo "$ASAN_BASE"; }
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$ROOT/fuzz/lsan.supp:print_suppressions=0"

# Core sources a harness links: projection needs only its own file; the
# others take the whole core (everything but the Python glue).
core_sources() {
    if [ "$1" = projection ]; then
        echo "$SRC/projection.c $SRC/status.c"
    else
        ls "$SRC"/*.c | grep -v -E '/(py_[^/]*|pymodule)\.c$' | tr '\n' ' '
    fi
}

build_one() {
    local h=$1 objdir=$OUT/obj-$1 objs=() src obj
    mkdir -p "$objdir"
    for src in $(core_sources "$h"); do
        obj=$objdir/$(basename "$src").o
        if [ ! -e "$obj" ] || [ "$src" -nt "$obj" ] || [ -n "$(find "$SRC" -name '*.h' -newer "$obj" | head -1)" ]; then
            $CC $CFLAGS $SAN -fsanitize=fuzzer-no-link $NOCMP -c "$src" -o "$obj"
        fi
        objs+=("$obj")
    done
    local harness=$ROOT/fuzz/fuzz_$h.c libs="-lm -lpthread"
    $CC $CFLAGS $SAN -fsanitize=fuzzer $NOCMP -c "$harness" -o "$objdir/harness.o"
    $CC $SAN -fsanitize=fuzzer "$objdir/harness.o" "${objs[@]}" $libs -o "$OUT/fuzz_$h"
    echo "fuzz: built $OUT/fuzz_$h"
}

run_one() { # harness, extra libFuzzer args...
    local h=$1; shift
    local work=$OUT/work-$h seeds=$ROOT/fuzz/corpus/$h
    mkdir -p "$work" "$seeds" "$OUT/crashes-$h"
    (cd "$OUT/crashes-$h" && ASAN_OPTIONS=$(asan_options "$h") "$OUT/fuzz_$h" -max_len="$(max_len "$h")" -timeout=10 \
        -rss_limit_mb="$(rss_limit "$h")" -malloc_limit_mb="$(rss_limit "$h")" -print_final_stats=1 \
        -artifact_prefix="$OUT/crashes-$h/" "$@" "$work" "$seeds")
}

cmd=${1:-smoke}
shift || true
[ "$cmd" = repro ] || bash tools/install_deps.sh fuzz
harnesses=("$@")
[ ${#harnesses[@]} -eq 0 ] && [ "$cmd" != repro ] && harnesses=("${ALL_HARNESSES[@]}")
mkdir -p "$OUT"

case $cmd in
build)
    for h in "${harnesses[@]}"; do build_one "$h"; done ;;
smoke)
    secs=${FUZZ_SMOKE_SECONDS:-20}
    for h in "${harnesses[@]}"; do
        build_one "$h"
        log=$OUT/smoke-$h.log
        if ! run_one "$h" -max_total_time="$secs" >"$log" 2>&1; then
            tail -60 "$log"; echo "fuzz: smoke $h FAILED (log $log)" >&2; exit 1
        fi
        echo "fuzz: smoke $h OK: $(grep -oE 'stat::number_of_executed_units: +[0-9]+' "$log" | grep -o '[0-9]*$') runs in ${secs}s"
    done ;;
full)
    runs=${FUZZ_RUNS:-10000000}
    maxs=${FUZZ_MAX_SECONDS:-3600}
    for h in "${harnesses[@]}"; do
        build_one "$h"
        log=$OUT/full-$h.log
        start=$(date +%s)
        set +e
        run_one "$h" -runs="$runs" -max_total_time="$maxs" >"$log" 2>&1
        rc=$?
        set -e
        secs=$(( $(date +%s) - start ))
        n=$(grep -oE 'stat::number_of_executed_units: +[0-9]+' "$log" | grep -o '[0-9]*$' | tail -1 || echo 0)
        eps=$(grep -oE 'stat::average_exec_per_sec: +[0-9]+' "$log" | grep -o '[0-9]*$' | tail -1 || echo 0)
        rss=$(grep -oE 'stat::peak_rss_mb: +[0-9]+' "$log" | grep -o '[0-9]*$' | tail -1 || echo 0)
        cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || echo 0)
        verdict="0 crashes, 0 leaks"
        [ "$rc" -ne 0 ] && verdict="FAILED (exit $rc, see fuzz/build/full-$h.log)"
        [ -e "$ROOT/fuzz/RESULTS.md" ] || printf '%s\n\n%s\n%s\n' "# Fuzz results (tools/fuzz.sh full)" \
            "| date (UTC) | commit | harness | executions | seconds | exec/s | coverage edges | peak RSS MB | result |" \
            "|---|---|---|---|---|---|---|---|---|" >"$ROOT/fuzz/RESULTS.md"
        printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$(date -u +%Y-%m-%dT%H:%MZ)" \
            "$(git rev-parse --short HEAD)" "$h${NOCMP:+ (no trace-cmp)}${OPENIMAGEIO_OPTIONS:+ (OPENIMAGEIO_OPTIONS=$OPENIMAGEIO_OPTIONS)}" "$n" "$secs" "$eps" "$cov" "$rss" "$verdict" >>"$ROOT/fuzz/RESULTS.md"
        echo "fuzz: full $h: $n executions in ${secs}s ($eps/s): $verdict"
        [ "$rc" -eq 0 ] || { tail -60 "$log"; exit 1; }
    done ;;
merge)
    for h in "${harnesses[@]}"; do
        build_one "$h"
        tmp=$OUT/merged-$h
        rm -rf "$tmp"; mkdir -p "$tmp"
        ASAN_OPTIONS=$(asan_options "$h") "$OUT/fuzz_$h" -merge=1 -max_len="$(max_len "$h")" "$tmp" "$ROOT/fuzz/corpus/$h" "$OUT/work-$h" >/dev/null 2>&1
        rm -rf "$ROOT/fuzz/corpus/$h"; mv "$tmp" "$ROOT/fuzz/corpus/$h"
        echo "fuzz: corpus $h: $(ls "$ROOT/fuzz/corpus/$h" | wc -l) files, $(cat "$ROOT"/fuzz/corpus/"$h"/* | wc -c) bytes"
    done ;;
repro)
    h=$1; shift
    build_one "$h"
    ASAN_OPTIONS=$(asan_options "$h") "$OUT/fuzz_$h" "$@" ;;
*)
    echo "usage: tools/fuzz.sh build|smoke|full|merge|repro [harness...]" >&2; exit 2 ;;
esac
