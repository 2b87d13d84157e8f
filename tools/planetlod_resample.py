#!/usr/bin/env python3
"""Resample an equirectangular (plate carree) map into a cube map.

    python3 -m tools.planetlod_resample INPUT OUTPUT [--projection qsc]
        [--size 1024] [--filter bilinear] [--format r16] [--layout cross|faces]

OUTPUT's extension picks the file type (.png, .tif, .exr, .jpg ...).  With
--layout faces six images are written: '{face}' in OUTPUT is replaced by the
face number, else '_face<N>' goes before the extension.  A progress bar goes
to stderr; Ctrl-C cancels and writes nothing.  OUTPUT's folder is created
if needed.  Exit status: 0 done, 1 error, 2 bad option, 130 cancelled.
"""
import argparse
import os
import sys
import time
import warnings

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

try:
    import planetlod
    planetlod.require_native()
except ImportError as exc:  # not built yet, or not run from the checkout
    sys.exit(f"planetlod_resample: cannot import the planetlod extension ({exc}); build it "
             f"with: cd {ROOT} && bash tools/build.sh, and run this as "
             "python3 -m tools.planetlod_resample from there")


class ProgressBar:
    """One line on stderr, redrawn at most every 0.1 s (and at 100 %): the
    bar, the elapsed time and the phase (reading, resampling, writing)."""

    def __init__(self, stream, width=40):
        self.stream = stream
        self.width = width
        self.start = time.monotonic()
        self.last = -1.0
        self.interrupted = False
        self.fraction = 0.0

    def draw(self, note):
        filled = int(round(self.fraction * self.width))
        bar = "#" * filled + "-" * (self.width - filled)
        elapsed = time.monotonic() - self.start
        self.stream.write(f"\r[{bar}] {self.fraction * 100:5.1f}%  {elapsed:6.2f} s  {note:<10}")
        self.stream.flush()

    def __call__(self, fraction):
        now = time.monotonic()
        if fraction < 1.0 and now - self.last < 0.1:
            return self.interrupted
        self.last = now
        self.fraction = fraction
        # planetlod.resample reports 0 before reading, 0.05..0.90 while
        # resampling and 1.0 once the file is written
        self.draw("reading" if fraction <= 0.0 else "resampling" if fraction < 0.9
                  else "writing" if fraction < 1.0 else "written")
        return self.interrupted

    def finish(self, note="done"):
        self.draw(note)
        self.stream.write("\n")
        self.stream.flush()


def parse_args(argv):
    parser = argparse.ArgumentParser(
        description="Resample an equirectangular map into a cube map (TSC, CSC or QSC).")
    parser.add_argument("input", help="equirectangular (2:1) image: PNG, JPEG, TIFF, EXR ...")
    parser.add_argument("output", help="output image; its extension picks the file type")
    parser.add_argument("--projection", default="qsc", choices=["tsc", "csc", "qsc", "spherified", "car"])
    parser.add_argument("--size", type=int, default=1024, help="face size in texels (1..16384)")
    parser.add_argument("--filter", default="bilinear", choices=list(planetlod.FILTERS))
    parser.add_argument("--format", default="r16", choices=list(planetlod.RESAMPLE_FORMATS),
                        help="rgba8, rgb8, r16 (heights), f32 (keeps channels), r8")
    parser.add_argument("--layout", default="cross", choices=["cross", "faces"])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if not 1 <= args.size <= 16384:
        parser.error(f"--size must be 1..16384, not {args.size}")
    if not 1 <= args.threads <= 16:
        parser.error(f"--threads must be 1..16, not {args.threads}")
    return args


def main(argv=None):
    args = parse_args(argv)
    out_dir = os.path.dirname(os.path.abspath(args.output))
    try:
        os.makedirs(out_dir, exist_ok=True)  # like the flyby: out/... just works
    except OSError as exc:
        print(f"planetlod_resample: error: cannot create {out_dir}: {exc}", file=sys.stderr)
        return 1
    bar = None if args.quiet else ProgressBar(sys.stderr)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            try:
                planetlod.resample(args.input, args.output, projection=args.projection, size=args.size,
                                   filter=args.filter, format=args.format, layout=args.layout,
                                   progress=bar, threads=args.threads)
            except KeyboardInterrupt:
                raise planetlod.Cancelled("interrupted")
        except planetlod.Cancelled:
            if bar:
                bar.finish("cancelled")
            print("planetlod_resample: cancelled, nothing written", file=sys.stderr)
            return 130
        except (planetlod.PlanetLODError, MemoryError) as exc:
            if bar:
                bar.finish("failed")
            print(f"planetlod_resample: error: {exc}", file=sys.stderr)
            return 1
        finally:
            for w in caught:
                print(f"planetlod_resample: warning: {w.message}", file=sys.stderr)
    if bar:
        bar.finish()
    return 0


if __name__ == "__main__":
    sys.exit(main())
