#!/bin/sh
# All benchmarks in one command (README "Benchmarks"):
#   bench/run_all.sh            full run (~4.5 min on 2 idle cores)
#   bench/run_all.sh --smoke    CI-sized run (< 60 s), results in bench/results/smoke
# Builds the extension in place if needed, then runs bench_path.py (parts 1, 2, 4),
# bench_blender.py (part 5: -b, and --gpu under xvfb-run when available),
# bench_cycles.py (part 3, full run only) and report.py (plots + README table).
set -eu
cd "$(dirname "$0")/.."
PY=${PYTHON:-/usr/bin/python3}
BLENDER=${BLENDER:-blender}
SMOKE=0
[ "${1:-}" = "--smoke" ] && SMOKE=1
if [ $SMOKE = 1 ]; then OUT=${BENCH_OUT:-bench/results/smoke}; else OUT=${BENCH_OUT:-bench/results}; fi
mkdir -p "$OUT"
bash tools/install_deps.sh bench
ls planetlod*.so >/dev/null 2>&1 || $PY setup.py -q build_ext --inplace
if [ $SMOKE = 1 ]; then
    CMD="bench/run_all.sh --smoke"
    nice $PY bench/bench_path.py --smoke --out "$OUT"
    nice "$BLENDER" -b --factory-startup --python-exit-code 1 --python bench/bench_blender.py \
        -- --frames 4 --quality DRAFT --out "$OUT" >"$OUT/blender.log" 2>&1 \
        || { tail -40 "$OUT/blender.log"; exit 1; }
else
    CMD="bench/run_all.sh"
    nice $PY bench/bench_path.py --out "$OUT"
    nice "$BLENDER" -b --factory-startup --python-exit-code 1 --python bench/bench_blender.py \
        -- --frames 36 --out "$OUT" >"$OUT/blender.log" 2>&1 || { tail -40 "$OUT/blender.log"; exit 1; }
    if command -v xvfb-run >/dev/null 2>&1; then
        nice xvfb-run -a -s "-screen 0 1280x720x24" "$BLENDER" --factory-startup \
            --python bench/bench_blender.py -- --gpu --frames 36 --out "$OUT" \
            >"$OUT/blender_gpu.log" 2>&1 || echo "GPU preview timing failed (see $OUT/blender_gpu.log)"
    fi
    BLENDER="$BLENDER" nice $PY bench/bench_cycles.py --out "$OUT"
fi
$PY bench/report.py --results "$OUT" --command "$CMD" \
    $( [ $SMOKE = 1 ] && echo --readme "$OUT/README.md" )
echo "bench/run_all.sh: results in $OUT"
