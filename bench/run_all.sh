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
ls planetlod/_native*.so >/dev/null 2>&1 || bash tools/build.sh
# Python runs the benchmarks as modules of the checkout (python3 -m bench.X);
# Blender runs them by path, with the checkout and its add-on on PYTHONPATH.
BLENDER_PYTHONPATH="$PWD:$PWD/addon"
if [ $SMOKE = 1 ]; then
    CMD="bench/run_all.sh --smoke"
    nice $PY -m bench.bench_path --smoke --out "$OUT"
    PYTHONPATH="$BLENDER_PYTHONPATH" nice "$BLENDER" -b --factory-startup --python-exit-code 1 --python bench/bench_blender.py \
        -- --frames 4 --quality DRAFT --out "$OUT" >"$OUT/blender.log" 2>&1 \
        || { tail -40 "$OUT/blender.log"; exit 1; }
else
    CMD="bench/run_all.sh"
    nice $PY -m bench.bench_path --out "$OUT"
    PYTHONPATH="$BLENDER_PYTHONPATH" nice "$BLENDER" -b --factory-startup --python-exit-code 1 --python bench/bench_blender.py \
        -- --frames 36 --out "$OUT" >"$OUT/blender.log" 2>&1 || { tail -40 "$OUT/blender.log"; exit 1; }
    if command -v xvfb-run >/dev/null 2>&1; then
        PYTHONPATH="$BLENDER_PYTHONPATH" nice xvfb-run -a -s "-screen 0 1280x720x24" "$BLENDER" --factory-startup \
            --python bench/bench_blender.py -- --gpu --frames 36 --out "$OUT" \
            >"$OUT/blender_gpu.log" 2>&1 || echo "GPU preview timing failed (see $OUT/blender_gpu.log)"
    fi
    BLENDER="$BLENDER" nice $PY -m bench.bench_cycles --out "$OUT"
fi
$PY -m bench.report --results "$OUT" --command "$CMD" \
    $( [ $SMOKE = 1 ] && echo --readme "$OUT/README.md" )
echo "bench/run_all.sh: results in $OUT"
