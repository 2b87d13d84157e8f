"""Last task of a Planet LOD flyby on a render farm (run inside Blender):

    blender -b --python farm/flamenco/merge_chunks.py -- \\
        --chunks OUT/chunks --frames 1-120 --out OUT

Each render task wrote its run of frames to a folder OUT/chunks/frames-A-B/
(frame_####.png, stats.csv, contact_sheet.png).  This moves every frame to
OUT/, writes OUT/stats.csv (the chunks' rows, unchanged, ordered by frame)
and OUT/contact_sheet.png.  It fails, changing nothing, when a frame of
--frames is missing, appears twice or was not asked for, or when chunks
disagree on the CSV columns.  Running it again after it succeeded gives the
same result.  Outside Blender (plain Python) it does all but the contact
sheet.
"""
import argparse
import csv
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class MergeError(Exception):
    pass


def parse_frames(spec):
    """'1-3,7,9..10' -> [1, 2, 3, 7, 9, 10] (Flamenco's frame-range notation)."""
    frames = set()
    for part in spec.replace("..", "-").split(","):
        ends = part.split("-")
        try:
            if len(ends) == 1:
                frames.add(int(ends[0]))
            elif len(ends) == 2:
                frames.update(range(int(ends[0]), int(ends[1]) + 1))
            else:
                raise ValueError(part)
        except ValueError:
            raise MergeError(f"bad frame range {spec!r}") from None
    if not frames:
        raise MergeError(f"frame range {spec!r} has no frames")
    return sorted(frames)


def frame_name(frame):
    return f"frame_{frame:04d}.png"


def read_chunks(chunks_dir):
    """(header line, {frame: (csv line, chunk folder)}) of every chunk's stats.csv."""
    if not os.path.isdir(chunks_dir):
        raise MergeError(f"no chunk folder {chunks_dir}")
    header = None
    rows = {}
    for name in sorted(os.listdir(chunks_dir)):
        folder = os.path.join(chunks_dir, name)
        stats = os.path.join(folder, "stats.csv")
        if not os.path.isfile(stats):
            continue
        with open(stats, newline="") as f:
            lines = f.read().splitlines()
        if not lines:
            raise MergeError(f"{stats} is empty")
        if header is None:
            header = lines[0]
        elif lines[0] != header:
            raise MergeError(f"{stats} has other columns than the chunks before it")
        columns = next(csv.reader([header]))
        if "frame" not in columns:
            raise MergeError(f"{stats} has no frame column")
        frame_column = columns.index("frame")
        for line in lines[1:]:
            frame = int(next(csv.reader([line]))[frame_column])
            if frame in rows:
                raise MergeError(f"frame {frame} is in two chunks: {rows[frame][1]} and {folder}")
            rows[frame] = (line, folder)
    if header is None:
        raise MergeError(f"no chunk in {chunks_dir} has a stats.csv")
    return header, rows


def merge(chunks_dir, frames, out_dir):
    """Moves the frames to out_dir and writes out_dir/stats.csv; returns the
    frame paths in order."""
    header, rows = read_chunks(chunks_dir)
    missing = [f for f in frames if f not in rows]
    extra = sorted(set(rows) - set(frames))
    if missing:
        raise MergeError(f"frames without a stats row: {missing}")
    if extra:
        raise MergeError(f"chunks hold frames that were not asked for: {extra}")
    moves = []
    for frame in frames:
        source = os.path.join(rows[frame][1], frame_name(frame))
        target = os.path.join(out_dir, frame_name(frame))
        if os.path.isfile(source):
            moves.append((source, target))
        elif not os.path.isfile(target):  # not moved by an earlier run either
            raise MergeError(f"frame {frame} has a stats row but no picture {source}")
    os.makedirs(out_dir, exist_ok=True)
    for source, target in moves:
        os.replace(source, target)
    stats = os.path.join(out_dir, "stats.csv")
    with open(stats + ".part", "w", newline="") as f:
        f.write("\n".join([header] + [rows[frame][0] for frame in frames]) + "\n")
    os.replace(stats + ".part", stats)
    return [os.path.join(out_dir, frame_name(frame)) for frame in frames]


def contact_sheet(paths, out_path):
    """The add-on's contact sheet (needs Blender and the planet_lod add-on:
    installed, or the repository's with PYTHONPATH naming addon/)."""
    import addon_utils
    if addon_utils.enable("planet_lod", default_set=True, handle_error=None) is None:
        raise SystemExit("merge_chunks: the planet_lod add-on is not installed: run "
                         "tools/install_addon.py, or run Blender with "
                         f"PYTHONPATH={os.path.join(REPO, 'addon')}")
    import planet_lod
    return planet_lod.contact_sheet(paths, out_path)


def main(argv):
    p = argparse.ArgumentParser(prog="blender -b --python farm/flamenco/merge_chunks.py --")
    p.add_argument("--chunks", required=True, help="folder of the chunk folders")
    p.add_argument("--frames", required=True, help="every frame of the job, e.g. 1-120")
    p.add_argument("--out", required=True, help="folder for the frames, stats.csv and contact sheet")
    args = p.parse_args(argv)
    try:
        frames = parse_frames(args.frames)
        paths = merge(args.chunks, frames, args.out)
    except MergeError as exc:
        raise SystemExit(f"merge_chunks: {exc}")
    print(f"merge_chunks: {len(paths)} frames and stats.csv in {args.out}", flush=True)
    if "bpy" in sys.modules:
        sheet = contact_sheet(paths, os.path.join(args.out, "contact_sheet.png"))
        print(f"merge_chunks: contact sheet {sheet}", flush=True)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
