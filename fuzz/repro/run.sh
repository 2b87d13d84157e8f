#!/usr/bin/env bash
# Builds and runs one reproducer against the core with asserts and
# ASan+UBSan:  bash fuzz/repro/run.sh NAME [args]
set -euo pipefail
cd "$(dirname "$0")/../.."
name=$1; shift
out=fuzz/build/repro-$name
mkdir -p fuzz/build
srcs=$(ls cext/*.c | grep -v -E '/(py_[^/]*|pymodule)\.c$')
clang -std=c11 -g -O1 -fsanitize=address,undefined -fno-sanitize-recover=all -D_POSIX_C_SOURCE=200809L \
    -Icext -c fuzz/repro/$name.c -o $out.o
objs=()
for s in $srcs; do clang -std=c11 -g -O1 -fsanitize=address,undefined -D_POSIX_C_SOURCE=200809L -Icext \
    -c $s -o $out-$(basename $s).o; objs+=($out-$(basename $s).o); done
clang -fsanitize=address,undefined $out.o "${objs[@]}" -lm -lpthread -o $out
exec $out "$@"
