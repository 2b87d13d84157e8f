"""Image files through planetlod.imageio (OpenImageIO's Python module), and a
native module that needs nothing but the C library."""
import os
import shutil
import subprocess
import sys

import pytest

np = pytest.importorskip("numpy")
pytest.importorskip("OpenImageIO")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_native_module_links_only_the_c_library(planetlod):
    readelf = shutil.which("readelf")
    if not readelf or not sys.platform.startswith("linux"):
        pytest.skip("readelf on Linux")
    out = subprocess.run([readelf, "-d", planetlod._native.__file__], capture_output=True,
                         text=True, check=True).stdout
    needed = sorted(line.split("[")[1].split("]")[0] for line in out.splitlines()
                    if "(NEEDED)" in line)
    if any(name.startswith(("libasan", "libubsan")) for name in needed):
        pytest.skip("a sanitizer build (tools/sanitize.sh) links the sanitizers' runtimes")
    allowed = ("libc.so", "libm.so", "libpthread.so", "libdl.so", "ld-linux")
    assert needed and all(name.startswith(allowed) for name in needed), needed


@pytest.mark.parametrize("dtype, stored, expect", [
    ("uint8", False, "u8"), ("uint16", False, "u16"), ("float", False, "f32"),
    ("int16", False, "f32"), ("int16", True, "i16"), ("int8", True, "f32"),
    ("uint16", True, "u16"),
])
def test_read_gives_typed_arrays(planetlod, tmp_path, dtype, stored, expect):
    import OpenImageIO as oiio
    from planetlod import imageio
    path = str(tmp_path / "m.tif")
    values = (np.arange(8 * 4 * 2).reshape(4, 8, 2) * 3 - 20).clip(
        0 if dtype.startswith("uint") else -128, 127).astype({"float": "float32"}.get(dtype, dtype))
    out = oiio.ImageOutput.create(path)
    assert out.open(path, oiio.ImageSpec(8, 4, 2, dtype))
    assert out.write_image(values)
    out.close()
    width, height, channels, got, pixels = imageio.read(path, stored=stored)
    assert (width, height, channels, got) == (8, 4, 2, expect)
    assert pixels.flags["C_CONTIGUOUS"] and pixels.size == 8 * 4 * 2
    if stored or dtype in ("uint8", "uint16", "float"):
        assert np.array_equal(pixels.reshape(values.shape).astype(np.float64),
                              values.astype(np.float64))


def test_write_refuses_lossy_types_and_removes_partial_files(planetlod, tmp_path):
    from planetlod import imageio
    pixels = np.zeros((4, 8, 1), np.float32)
    with pytest.raises(planetlod.InvalidArgument, match="cannot hold float32"):
        imageio.write(str(tmp_path / "a.png"), pixels, 8, 4, 1, "f32")
    with pytest.raises(planetlod.FileError, match="cannot write|no image writer"):
        imageio.write(str(tmp_path / "missing" / "a.tif"), pixels, 8, 4, 1, "f32")
    assert not (tmp_path / "a.png").exists()


def test_row_reader_reads_bands_of_channel_0(planetlod, tmp_path):
    import OpenImageIO as oiio
    from planetlod import imageio
    path = str(tmp_path / "r.png")
    values = np.arange(16 * 8 * 3, dtype=np.uint16).reshape(8, 16, 3)
    out = oiio.ImageOutput.create(path)
    assert out.open(path, oiio.ImageSpec(16, 8, 3, "uint16"))
    assert out.write_image(values)
    out.close()
    rows = imageio.RowReader(path)
    assert (rows.width, rows.height, rows.dtype) == (16, 8, "u16")
    band = rows.read(2, 5)
    assert np.array_equal(band.reshape(3, 16), values[2:5, :, 0])
    with pytest.raises(planetlod.InvalidArgument):
        rows.read(5, 9)
    rows.close()


def test_missing_openimageio_names_what_to_install(tmp_path):
    """Without OpenImageIO's Python module an image file fails with an
    ImportError that is also a PlanetLODError (the add-on reports it), naming
    the wheel and Debian's package; nothing is written."""
    code = f"""
import sys
sys.modules['OpenImageIO'] = None  # any 'import OpenImageIO' now fails
import planetlod
try:
    planetlod.resample({os.path.join(ROOT, 'data', 'earth-topology.png')!r},
                       {str(tmp_path / 'n.png')!r}, size=16)
except ImportError as exc:
    print(isinstance(exc, planetlod.PlanetLODError), 'pip install OpenImageIO' in str(exc),
          'python3-openimageio' in str(exc))
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", "True", "True"]
    assert not (tmp_path / "n.png").exists()
