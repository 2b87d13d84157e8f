"""What a flyby writes besides its frames: one CSV row per frame, the
contact sheet's layout, and the frame ranges it is given.

Headless `-a` renders through a planet_lod_geo camera write one stats file per
frame (FRAME_STATS_FOLDER beside the frames), so that chunks rendered at the
same time on several machines never write the same file; merge_frame_stats()
then writes the one stats.csv, rows in frame order."""
import math
import os
import re

from . import FileError, InvalidArgument

CSV_FIELDS = ("frame", "sectors_total", "sectors_after_backface", "sectors_after_frustum",
              "sectors_after_budget", "triangles", "vertices", "splits", "merges", "max_level",
              "refine_us", "mesh_ms", "render_s", "camera_altitude_m", "camera_ground_m",
              "mesh_hash")


def csv_row(values):
    return ",".join(str(values.get(name, "")) for name in CSV_FIELDS)


FRAME_STATS_FOLDER = "planet_lod_stats"
_FRAME_STATS_NAME = re.compile(r"^frame_(-?\d+)\.csv$")


def frame_stats_path(frames_folder, frame):
    return os.path.join(frames_folder, FRAME_STATS_FOLDER, f"frame_{frame:06d}.csv")


def write_frame_stats(frames_folder, row):
    """Writes row (a dict with "frame") as its frame's own stats file, whole or
    not at all (a re-run chunk replaces it); returns its path."""
    path = frame_stats_path(frames_folder, int(row["frame"]))
    partial = f"{path}.{os.getpid()}.partial"
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(partial, "w") as f:
            f.write(",".join(CSV_FIELDS) + "\n" + csv_row(row) + "\n")
        os.replace(partial, path)
    except OSError as exc:
        raise FileError(str(exc)) from exc
    return path


def merge_frame_stats(frames_folder, frames=None):
    """Writes frames_folder/stats.csv from the per-frame stats files, one row
    per frame in frame order; returns the number of rows, 0 (and writes
    nothing) when the render wrote none (its camera is not a planet_lod_geo
    camera). With `frames` (a list, or a range text such as "1-10,20") every
    one of them must have its row, and no other frame may."""
    folder = os.path.join(frames_folder, FRAME_STATS_FOLDER)
    if not os.path.isdir(folder):
        return 0
    header, rows = ",".join(CSV_FIELDS), {}
    for name in sorted(os.listdir(folder)):
        match = _FRAME_STATS_NAME.match(name)
        if not match:
            continue
        with open(os.path.join(folder, name)) as f:
            lines = f.read().splitlines()
        if len(lines) != 2 or lines[0] != header:
            raise InvalidArgument(f"{os.path.join(folder, name)}: not a frame's stats "
                                  f"(a header of {len(CSV_FIELDS)} columns and one row)")
        rows[int(match.group(1))] = lines[1]
    if frames is not None:
        wanted = set(parse_frame_list(frames) if isinstance(frames, str) else frames)
        missing, extra = sorted(wanted - set(rows)), sorted(set(rows) - wanted)
        if missing:
            raise InvalidArgument(f"frames without stats in {folder}: {missing}")
        if extra:
            raise InvalidArgument(f"stats of frames not asked for in {folder}: {extra}")
    stats = os.path.join(frames_folder, "stats.csv")
    try:
        with open(stats + ".partial", "w") as f:
            f.write("\n".join([header] + [rows[frame] for frame in sorted(rows)]) + "\n")
        os.replace(stats + ".partial", stats)
    except OSError as exc:
        raise FileError(str(exc)) from exc
    return len(rows)


def parse_frame_list(text):
    """'1-3,7,10..12,20-24:2' -> [1, 2, 3, 7, 10, 11, 12, 20, 22, 24]
    (Flamenco's and OpenJD's notations); raises InvalidArgument."""
    frames = set()
    for part in text.replace(" ", "").split(","):
        ends = re.fullmatch(r"(-?\d+)(?:(?:-|\.\.)(-?\d+)(?::([1-9]\d*))?)?", part)
        if not ends:
            raise InvalidArgument(f"bad frame range {text!r}")
        first = int(ends.group(1))
        last = int(ends.group(2)) if ends.group(2) is not None else first
        if last < first:
            raise InvalidArgument(f"bad frame range {text!r}")
        frames.update(range(first, last + 1, int(ends.group(3) or 1)))
    return sorted(frames)


def contact_sheet_layout(count, thumb_w, thumb_h, columns=None, gap=2):
    """(sheet_w, sheet_h, [(x, y) of each thumbnail's lower-left corner])."""
    if count <= 0:
        return 0, 0, []
    columns = columns or max(1, min(count, int(math.ceil(math.sqrt(count * 16 / 9.0)))))
    rows = (count + columns - 1) // columns
    width = columns * thumb_w + (columns + 1) * gap
    height = rows * thumb_h + (rows + 1) * gap
    places = []
    for i in range(count):
        col, row = i % columns, i // columns
        places.append((gap + col * (thumb_w + gap), height - (row + 1) * (thumb_h + gap)))
    return width, height, places


def parse_frames(text):
    """'1-120' or '7' -> (first, last); raises InvalidArgument."""
    parts = text.split("-")
    if len(parts) > 2:
        raise InvalidArgument(f"bad frame range {text!r} (want A-B)")
    try:
        numbers = [int(part) for part in parts]
    except ValueError as exc:  # int()'s own message, as a domain error
        raise InvalidArgument(str(exc)) from None
    first, last = numbers[0], numbers[-1]
    if first < 0 or last < first:
        raise InvalidArgument(f"bad frame range {text!r}")
    return first, last
