"""Helpers of the robustness tests (tests/blender/test_robust_*.py): bad input
files, a whole-scene snapshot, and "this must fail with a readable report"."""
import hashlib
import os
import struct
import zlib

import bpy


# ---- bad height maps ------------------------------------------------------------

def _png_chunk(tag, data):
    return (struct.pack(">I", len(data)) + tag + data
            + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF))


def write_grey_png(path, width, height, value=0):
    """A real 8-bit grey PNG of one value; a 30000x15000 one deflates to ~0.4 MB."""
    comp = zlib.compressobj(9)
    row = b"\0" + bytes([value]) * width
    data = b"".join(comp.compress(row) for _ in range(height)) + comp.flush()
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(_png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)))
        f.write(_png_chunk(b"IDAT", data))
        f.write(_png_chunk(b"IEND", b""))
    return path


def write_float_tiff(path, width, height, value):
    """An uncompressed one-channel 32-bit float TIFF of one value, written by hand
    (Blender's own image writer replaces NaN pixels)."""
    pixels = struct.pack(f"<{width * height}f", *([value] * (width * height)))
    tags = [(256, 4, width), (257, 4, height), (258, 3, 32), (259, 3, 1), (262, 3, 1),
            (273, 4, 8), (277, 3, 1), (278, 4, height), (279, 4, len(pixels)), (339, 3, 3)]
    ifd = struct.pack("<H", len(tags))
    for tag, kind, count_value in tags:
        ifd += struct.pack("<HHI", tag, kind, 1)
        ifd += struct.pack("<HH" if kind == 3 else "<I", *((count_value, 0) if kind == 3
                                                            else (count_value,)))
    ifd += struct.pack("<I", 0)
    with open(path, "wb") as f:
        f.write(b"II*\0" + struct.pack("<I", 8 + len(pixels)))
        f.write(pixels)
        f.write(ifd)
    return path


def bad_heightmaps(folder):
    """{case: path} of every bad height map the robustness tests use (the missing one absent)."""
    os.makedirs(folder, exist_ok=True)
    paths = {"missing": os.path.join(folder, "missing.png")}
    zero = paths["zero-byte"] = os.path.join(folder, "zero.png")
    open(zero, "wb").close()
    corrupt = paths["corrupt"] = os.path.join(folder, "corrupt.png")
    with open(corrupt, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + b"not really a png" * 64)
    paths["30000x15000"] = write_grey_png(os.path.join(folder, "huge.png"), 30000, 15000)
    paths["NaN tiff"] = write_float_tiff(os.path.join(folder, "nan.tif"), 64, 32, float("nan"))
    return paths


# ---- scene snapshot --------------------------------------------------------------

def _mesh_digest(mesh):
    h = hashlib.sha1()
    coords = [0.0] * (3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", coords)
    h.update(struct.pack(f"{len(coords)}f", *coords))
    h.update(repr((len(mesh.vertices), len(mesh.polygons))).encode())
    return h.hexdigest()


def snapshot():
    """Everything a failed operation must leave as it was: datablock names and
    counts, planet settings, mesh geometry, scene camera and frame."""
    from planet_lod import props
    state = {}
    for kind in ("objects", "meshes", "images", "materials", "cameras", "node_groups",
                 "collections"):
        coll = getattr(bpy.data, kind)
        state[kind] = sorted(item.name for item in coll)
        state["orphan " + kind] = sorted(item.name for item in coll if item.users == 0)
    scene = bpy.context.scene
    state["scene camera"] = scene.camera.name if scene.camera else None
    state["frame"] = scene.frame_current
    state["render filepath"] = scene.render.filepath
    for obj in bpy.data.objects:
        if obj.type == 'MESH' and obj.planet_lod.enabled:
            s = obj.planet_lod
            state["settings " + obj.name] = {n: repr(getattr(s, n)) for n in props.SETTING_NAMES}
            state["insets " + obj.name] = [inset.filepath for inset in s.insets]
            state["mesh " + obj.name] = _mesh_digest(obj.data)
            state["matrix " + obj.name] = repr(obj.matrix_world)
        if obj.type == 'CAMERA':
            state["camera " + obj.name] = (repr(obj.matrix_world), obj.data.type,
                                           obj.data.ortho_scale, obj.data.lens)
    return state


def assert_same(before, after, label):
    if before != after:
        diff = {k: (before.get(k), after.get(k)) for k in set(before) | set(after)
                if before.get(k) != after.get(k)}
        raise AssertionError(f"{label}: the scene changed: {diff}")


def expect_error(label, call, *words):
    """call() must fail with an ERROR report (RuntimeError in background mode) or a
    clear exception naming one of `words`; returns the message."""
    try:
        result = call()
    except (RuntimeError, ValueError, OSError) as exc:
        message = str(exc)
        assert any(w.lower() in message.lower() for w in words), \
            f"{label}: unclear message {message!r} (want one of {words})"
        print(f"robust: {label}: reported: {message.strip()}", flush=True)
        return message
    raise AssertionError(f"{label}: accepted (returned {result})")
