#!/usr/bin/env python3
"""CubeResampler benchmark: 4096x2048 equirectangular -> 6 x 1024^2 cube map.

    python3 -m bench.bench_resample [--size 1024] [--repeat 3] [--projection qsc]

Prints the best-of-N resampling time (the C resampler alone, as reported by
planetlod.resample), and the read and write times, for the Blue Marble RGB map
and a 4096x2048 16-bit grey map (the Earth topology upsampled with the CAR
resampler), against the 1 s target.  "cpu s" is the calling thread's CPU
time: with 1 thread the whole compute cost, robust on a busy machine.  Not a
test: figures only.
"""
import argparse
import os
import platform
import sys
import tempfile

import planetlod

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

TARGET_S = 1.0


def data(name):
    for d in (os.path.join(ROOT, "data"), os.path.join(os.path.dirname(ROOT), "shared", "data")):
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    sys.exit(f"bench_resample: data file {name} not found")


def best(runs, key):
    return min(r[key] for r in runs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--projection", default="qsc")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        grey = os.path.join(tmp, "grey4096.png")
        planetlod.resample(data("earth-topology.png"), grey, projection="car", size=2048, format="r16")
        inputs = [("blue marble 4096x2048 RGB u8", data("earth-blue-marble.jpg"), "rgb8", ".png"),
                  ("topology 4096x2048 grey u16", grey, "r16", ".png"),
                  ("topology 4096x2048 grey u16", grey, "f32", ".tif")]
        print(f"# CubeResampler, {args.projection}, 4096x2048 -> 6 x {args.size}^2; best of {args.repeat}")
        print(f"# machine: {platform.machine()}, {os.cpu_count()} cpus, {platform.platform()}, "
              f"load {os.getloadavg()[0]:.2f}")
        print(f"{'input':32} {'format':6} {'filter':9} {'threads':>7} {'resample s':>10} "
              f"{'cpu s':>6} {'read s':>7} {'write s':>8} {'vs 1 s':>7}")
        for label, path, fmt, ext in inputs:
            out = os.path.join(tmp, "out" + ext)
            for filter_name in ("nearest", "bilinear", "bicubic"):
                for threads in (1, 2):
                    if filter_name != "bilinear" and threads == 1:
                        continue
                    runs = [planetlod.resample(path, out, projection=args.projection, size=args.size,
                                               filter=filter_name, format=fmt, threads=threads)
                            for _ in range(args.repeat)]
                    t = best(runs, "resample_s")
                    print(f"{label:32} {fmt:6} {filter_name:9} {threads:7d} {t:10.3f} "
                          f"{best(runs, 'resample_thread_cpu_s'):6.3f} {best(runs, 'read_s'):7.3f} {best(runs, 'write_s'):8.3f} "
                          f"{'OK' if t < TARGET_S else 'SLOW':>7}")


if __name__ == "__main__":
    main()
