"""The module loads and its Buffer honours the buffer protocol as Blender needs."""
import array


def test_exceptions_hierarchy(planetlod):
    assert issubclass(planetlod.InvalidArgument, ValueError)
    assert issubclass(planetlod.InvalidArgument, planetlod.PlanetLODError)
    assert issubclass(planetlod.FileError, OSError)
    assert issubclass(planetlod.ImageError, ValueError)


def test_buffer_type_exists(planetlod):
    assert planetlod.Buffer.__name__ == "Buffer"
