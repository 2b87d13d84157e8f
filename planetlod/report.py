"""What a flyby writes besides its frames: one CSV row per frame, the
contact sheet's layout, and the frame ranges it is given."""
import math

from . import InvalidArgument

CSV_FIELDS = ("frame", "sectors_total", "sectors_after_backface", "sectors_after_frustum",
              "sectors_after_budget", "triangles", "vertices", "splits", "merges", "max_level",
              "refine_us", "mesh_ms", "render_s", "camera_altitude_m", "camera_ground_m",
              "mesh_hash")


def csv_row(values):
    return ",".join(str(values.get(name, "")) for name in CSV_FIELDS)


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
