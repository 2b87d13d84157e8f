"""The module loads and its Buffer honours the buffer protocol as Blender needs."""
import array


def test_exceptions_hierarchy(planetlod):
    assert issubclass(planetlod.InvalidArgument, ValueError)
    assert issubclass(planetlod.InvalidArgument, planetlod.PlanetLODError)
    assert issubclass(planetlod.FileError, OSError)
    assert issubclass(planetlod.ImageError, ValueError)


def test_buffer_type_exists(planetlod):
    assert planetlod.Buffer.__name__ == "Buffer"


def test_addon_projections_are_the_cores(planetlod):
    """The add-on's projection choices (props.PROJECTION_ITEMS, read without
    bpy) are the extension's PROJECTIONS, which planets.projection_id maps to."""
    import ast
    import os
    from planetlod import planets
    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                        "addon", "planet_lod", "props.py")
    tree = ast.parse(open(path, encoding="utf-8").read())
    items = next(node.value for node in tree.body if isinstance(node, ast.Assign)
                 and getattr(node.targets[0], "id", "") == "PROJECTION_ITEMS")
    keys = [ast.literal_eval(item)[0] for item in items.elts]
    assert sorted(planets.projection_id(key) for key in keys) == sorted(planetlod.PROJECTIONS)
    try:
        planets.projection_id("MERCATOR")
    except planetlod.InvalidArgument as exc:
        assert "MERCATOR" in str(exc)
    else:
        raise AssertionError("an unknown projection was accepted")
