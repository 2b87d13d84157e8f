"""Image files for the core, through OpenImageIO's Python module (bpy-free).

The C extension decodes no image format: it reads the headerless height
grids (.hgt, .r16, .raw) and GeoTIFF tags itself and asks this module for
everything else.  `read` gives a whole image as a typed array, `RowReader`
a band of rows at a time (maps larger than memory), `write` stores a typed
buffer; the extension takes the arrays in without a copy where it can.

Where OpenImageIO's Python module comes from (`openimageio()` finds it):

* plain Python: the `OpenImageIO` wheel from PyPI
  (`python3 -m pip install OpenImageIO`);
* Debian's /usr/bin/python3 and Debian's Blender 3.4: `python3-openimageio`;
* Blender 4.5 and later bundle it: a real Blender has it on `sys.path`; the
  `bpy` wheels keep it under `bpy.utils.resource_path('LOCAL')/python`,
  which is added to `sys.path` here;
* the `bpy` 4.2 wheel lacks it: the PyPI wheel installed beside it.

Errors carry the message without context; the extension adds its own
("planetlod.CubeMap.from_image: ..."): `FileError` for missing, unreadable
or unwritable files, `ImageError` for corrupt or unsupported images,
`InvalidArgument` for a file type that cannot hold the pixels, MemoryError.
A missing OpenImageIO (or NumPy) raises `MissingModule`, an ImportError and a
`PlanetLODError` (the add-on reports it), naming what to install.
"""
import os
import stat
import struct
import sys

DEFAULT_MAX_PIXELS = 1 << 28

# sample types as the extension names them: numpy dtype, OpenImageIO type
_SAMPLE_TYPES = {
    "u8": ("uint8", "uint8"),
    "u16": ("uint16", "uint16"),
    "i16": ("int16", "int16"),
    "f32": ("float32", "float"),
}
_TYPE_NAMES = {"u8": "8-bit", "u16": "16-bit", "i16": "16-bit signed", "f32": "float32"}

_openimageio = None


def _errors():
    from . import FileError, ImageError, InvalidArgument
    return FileError, ImageError, InvalidArgument


_missing_class = None


def _missing(message):
    """MissingModule(message): the class is made on first use, from the
    extension's PlanetLODError (or its stand-in)."""
    global _missing_class
    if _missing_class is None:
        from . import PlanetLODError

        class MissingModule(PlanetLODError, ImportError):
            """A module planetlod needs for image files cannot be imported."""

        MissingModule.__qualname__ = "MissingModule"
        _missing_class = MissingModule
    return _missing_class(message)


def _blender_site_packages():
    """Site-packages of the Python a `bpy` wheel bundles (None outside one)."""
    bpy = sys.modules.get("bpy")
    utils = getattr(bpy, "utils", None)
    if utils is None or not hasattr(utils, "resource_path"):
        return []
    try:
        local = utils.resource_path("LOCAL")
    except Exception:  # a stand-in bpy (tests) or a Blender without it
        return []
    if not local:
        return []
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    return [os.path.join(local, "python", "lib", version, "site-packages"),
            os.path.join(local, "python", "lib", "site-packages")]


def openimageio():
    """OpenImageIO's Python module; MissingModule (an ImportError) naming what
    to install."""
    global _openimageio
    if _openimageio is not None:
        return _openimageio
    try:
        import OpenImageIO
    except ImportError:
        OpenImageIO = None
        for path in _blender_site_packages():
            if os.path.isdir(os.path.join(path, "OpenImageIO")) and path not in sys.path:
                sys.path.append(path)
                try:
                    import OpenImageIO
                except ImportError:
                    OpenImageIO = None
                break
    if OpenImageIO is not None:
        try:  # its arrays are NumPy's
            import numpy  # noqa: F401
        except ImportError:
            raise _missing(
                "planetlod reads and writes images with OpenImageIO's Python module, whose "
                f"arrays need NumPy, which this Python ({sys.executable}) cannot import: "
                "install it (python3 -m pip install numpy; Debian: apt install "
                "python3-numpy)") from None
    if OpenImageIO is None:
        raise _missing(
            "planetlod reads and writes images with OpenImageIO's Python module, which "
            f"this Python ({sys.executable}, {sys.version.split()[0]}) cannot import: "
            "install the OpenImageIO wheel (python3 -m pip install OpenImageIO); for "
            "Debian's system Python and Blender 3.4: apt install python3-openimageio; "
            "Blender 4.5 and later bundle it")
    _openimageio = OpenImageIO
    return OpenImageIO


def _why(text):
    return f": {text}" if text else ""


def _exr_header_plausible(path, file_size):
    """OpenEXR allocates each header attribute's declared size before reading
    it, so a few hundred corrupt bytes can demand gigabytes.  Walks the first
    header's attributes (name, type, int32 size, value) and refuses a size
    larger than the file.  True: not an EXR, or a plausible header."""
    try:
        f = open(path, "rb")
    except OSError:
        return True  # the reader reports it
    with f:
        head = f.read(8)
        if len(head) < 8 or head[:4] != b"\x76\x2f\x31\x01":
            return True
        for _ in range(1024):
            c = f.read(1)
            if not c or c == b"\0":
                return True  # end of header (or truncated: the reader reports it)
            strings = 0
            while strings < 2 and c:  # attribute name, then type name
                c = f.read(1)
                strings += c == b"\0"
            size = f.read(4) if c else b""
            if len(size) != 4:
                return True
            (size,) = struct.unpack("<I", size)
            if size > file_size:
                return False
            f.seek(size, os.SEEK_CUR)
    return True


def _check_file(path):
    FileError, ImageError, _ = _errors()
    try:
        info = os.stat(path)
    except OSError as exc:
        raise FileError(f"cannot open '{path}': {os.strerror(exc.errno)}") from None
    if not stat.S_ISREG(info.st_mode):
        raise FileError(f"'{path}' is not a regular file")
    try:
        open(path, "rb").close()
    except OSError as exc:
        raise FileError(f"cannot read '{path}': {os.strerror(exc.errno)}") from None
    if info.st_size == 0:
        raise ImageError(f"'{path}' is empty (0 bytes)")
    if not _exr_header_plausible(path, info.st_size):
        raise ImageError(f"'{path}' is a corrupt OpenEXR file (a header attribute is larger "
                         "than the file)")


_SGI_EXTENSIONS = (".sgi", ".rgb", ".rgba", ".bw", ".int", ".inta")


def _is_sgi(path):
    if os.path.splitext(path)[1].lower() in _SGI_EXTENSIONS:
        return True
    try:
        with open(path, "rb") as f:
            return f.read(2) == b"\x01\xda"  # the SGI magic number, big-endian 474
    except OSError:
        return False


def _refuse_sgi(path):
    # OpenImageIO 2.4's SGI reader writes past the caller's buffer on corrupt
    # RLE data and news negative sizes; heightmaps do not come as SGI, so it
    # is refused, by name and by its magic number before any reader sees
    # it, rather than trusted with the process's heap.
    _, ImageError, _ = _errors()
    raise ImageError(f"'{path}' is an SGI image; SGI is not supported (use PNG, TIFF or EXR)")


def _open_input(path):
    _, ImageError, _ = _errors()
    oiio = openimageio()
    if _is_sgi(path):
        _refuse_sgi(path)
    image = oiio.ImageInput.open(path)
    if image is None:
        raise ImageError(f"'{path}' is not a readable image{_why(oiio.geterror())}")
    if image.format_name() == "sgi":
        image.close()
        _refuse_sgi(path)
    return image


def _basetype(oiio, spec):
    base = spec.format.basetype
    for name in ("UINT8", "INT8", "UINT16", "INT16", "UINT32", "INT32"):
        if base == getattr(oiio, name):
            return name.lower()
    return "float"


def _read_pixels(image, path, fmt):
    _, ImageError, _ = _errors()
    spec = image.spec()
    try:
        pixels = image.read_image(0, 0, 0, spec.nchannels, fmt)
    except MemoryError:
        raise MemoryError(f"out of memory reading '{path}'") from None
    except Exception as exc:  # a decoder that throws
        raise ImageError(f"reading '{path}' failed: {exc}") from None
    if pixels is None:
        raise ImageError(f"'{path}' is corrupt or truncated{_why(image.geterror())}")
    return pixels


def read(path, stored=False, max_pixels=DEFAULT_MAX_PIXELS):
    """The first subimage of an image file: (width, height, channels, dtype,
    pixels), pixels a C-contiguous array of height x width x channels samples,
    dtype 'u8', 'u16', 'i16' or 'f32'.

    stored=False keeps u8 and u16 and gives every other type as f32 (as
    OpenImageIO converts: integers normalised); stored=True gives samples as
    stored, for data whose values are quantities (a DEM's metres): u8, u16
    and i16 as they are, other integers as f32 holding their values, floats
    as f32.  More than 4 channels or more than max_pixels pixels are refused
    before any pixel is decoded."""
    FileError, ImageError, _ = _errors()
    path = os.fsdecode(path)
    _check_file(path)
    openimageio()
    import numpy as np

    image = _open_input(path)
    try:
        spec = image.spec()
        if spec.width <= 0 or spec.height <= 0 or spec.depth != 1 or spec.deep:
            raise ImageError(f"'{path}' has an unsupported size or layout ({spec.width}x"
                             f"{spec.height}x{spec.depth}{', deep' if spec.deep else ''})")
        if spec.nchannels < 1 or spec.nchannels > 4:
            raise ImageError(f"'{path}' has {spec.nchannels} channels; 1 to 4 are supported")
        max_pixels = max_pixels or DEFAULT_MAX_PIXELS
        if spec.width * spec.height > max_pixels:
            raise ImageError(f"'{path}' is {spec.width}x{spec.height} pixels, more than the "
                             f"limit of {max_pixels}")
        oiio = openimageio()
        base = _basetype(oiio, spec)
        uniform = not spec.channelformats
        if not stored:
            dtype = {"uint8": "u8", "uint16": "u16"}.get(base, "f32")
            pixels = _read_pixels(image, path, _SAMPLE_TYPES[dtype][1])
        elif uniform and base in ("uint8", "uint16", "int16"):
            dtype = {"uint8": "u8", "uint16": "u16", "int16": "i16"}[base]
            pixels = _read_pixels(image, path, _SAMPLE_TYPES[dtype][1])
        elif uniform and base in ("int8", "uint32", "int32"):
            dtype = "f32"
            pixels = _read_pixels(image, path, base).astype(np.float32)
        else:  # floats keep their values anyway
            dtype = "f32"
            pixels = _read_pixels(image, path, "float")
        pixels = np.ascontiguousarray(pixels, dtype=_SAMPLE_TYPES[dtype][0])
        if pixels.size != spec.width * spec.height * spec.nchannels:
            raise ImageError(f"'{path}' is corrupt or truncated{_why(image.geterror())}")
        return spec.width, spec.height, spec.nchannels, dtype, pixels
    finally:
        image.close()


def _writer_holds(ext, dtype):
    """Whether a file type we know stores `dtype` without loss; unknown
    extensions are left to OpenImageIO."""
    if ext in ("png", "ppm", "pgm", "pnm"):
        return dtype in ("u8", "u16")
    if ext in ("jpg", "jpeg", "bmp", "tga", "gif"):
        return dtype == "u8"
    if ext in ("exr", "hdr", "pfm"):
        return dtype == "f32"
    return True


def write(path, pixels, width, height, channels, dtype, attributes=()):
    """Writes width x height texels of `channels` interleaved samples
    (`pixels`: a buffer of dtype 'u8', 'u16' or 'f32', rows top to bottom)
    in the format the extension chooses; `attributes`: (name, value) pairs
    for the encoder (OpenImageIO's, e.g. ("compression", "jpeg:95")).  A
    partly written file is removed."""
    FileError, _, InvalidArgument = _errors()
    path = os.fsdecode(path)
    ext = os.path.splitext(path)[1][1:].lower()
    if not _writer_holds(ext, dtype):
        raise InvalidArgument(f"a .{ext} file cannot hold {_TYPE_NAMES[dtype]} pixels "
                              f"('{path}')")
    oiio = openimageio()
    import numpy as np

    output = oiio.ImageOutput.create(path)
    if output is None:
        raise FileError(f"no image writer for '{path}'{_why(oiio.geterror())}")
    array = np.frombuffer(pixels, dtype=_SAMPLE_TYPES[dtype][0])
    array = array.reshape(height, width, channels)
    spec = oiio.ImageSpec(width, height, channels, _SAMPLE_TYPES[dtype][1])
    for name, value in attributes:
        spec.attribute(name, value)
    if not output.open(path, spec):
        raise FileError(f"cannot write '{path}'{_why(output.geterror())}")
    try:
        ok = output.write_image(array)
        why = "" if ok else output.geterror()
    except Exception as exc:  # an encoder that throws
        ok, why = False, str(exc)
    ok = output.close() and ok
    if not ok:
        why = why or output.geterror()
        try:
            os.remove(path)
        except OSError:
            pass
        raise FileError(f"writing '{path}' failed{_why(why)}")


class RowReader:
    """Channel 0 of an image a band of rows at a time, for maps larger than
    memory: `width`, `height`, `dtype` ('u8', 'u16' kept, other types 'f32'
    as `read` converts them) and `read(y0, y1)`."""

    def __init__(self, path):
        FileError, ImageError, _ = _errors()
        path = os.fsdecode(path)
        try:
            regular = stat.S_ISREG(os.stat(path).st_mode)
        except OSError:
            regular = False
        if not regular:
            raise FileError(f"cannot open '{path}'")
        if not _exr_header_plausible(path, os.path.getsize(path)):
            raise ImageError(f"'{path}' is a corrupt OpenEXR file")
        oiio = openimageio()
        image = None if _is_sgi(path) else oiio.ImageInput.open(path)
        if image is None and not _is_sgi(path):
            raise ImageError(f"'{path}' is not a readable image{_why(oiio.geterror())}")
        spec = image.spec() if image is not None else None
        if (image is None or image.format_name() == "sgi" or spec.width <= 0 or spec.height <= 0
                or spec.depth != 1 or spec.deep or spec.nchannels < 1):
            if image is not None:
                image.close()
            raise ImageError(f"'{path}' has an unsupported format or layout")
        base = _basetype(oiio, spec)
        self.path = path
        self.width = spec.width
        self.height = spec.height
        self.dtype = {"uint8": "u8", "uint16": "u16"}.get(base, "f32")
        self._image = image

    def read(self, y0, y1):
        """Rows [y0, y1) of channel 0: a C-contiguous array of (y1 - y0) x width samples."""
        import numpy as np

        _, ImageError, InvalidArgument = _errors()
        if self._image is None:
            raise InvalidArgument(f"'{self.path}' is closed")
        if y0 < 0 or y1 > self.height or y0 >= y1:
            raise InvalidArgument(f"rows {y0}..{y1} outside 0..{self.height}")
        try:
            rows = self._image.read_scanlines(0, 0, y0, y1, 0, 0, 1,
                                              _SAMPLE_TYPES[self.dtype][1])
        except MemoryError:
            raise MemoryError(f"out of memory reading '{self.path}'") from None
        except Exception as exc:
            raise ImageError(f"rows {y0}..{y1} are corrupt or truncated: {exc}") from None
        if rows is None:
            raise ImageError(f"rows {y0}..{y1} are corrupt or truncated"
                             f"{_why(self._image.geterror())}")
        return np.ascontiguousarray(rows, dtype=_SAMPLE_TYPES[self.dtype][0])

    def close(self):
        if self._image is not None:
            self._image.close()
            self._image = None
