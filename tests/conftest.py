"""Shared fixtures: the built module and the real planetary maps."""
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

DATA_DIRS = [os.path.join(ROOT, "data"), os.path.join(os.path.dirname(ROOT), "shared", "data")]


def data_path(name):
    """Path of a bundled map (data/), else of ../shared/data; skip if absent."""
    for d in DATA_DIRS:
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    pytest.skip(f"data file {name} not available")


@pytest.fixture(scope="session")
def planetlod():
    import planetlod as module
    return module


# tests/blender/ holds scripts that run inside Blender (driven by
# test_blender.py), not pytest modules.
collect_ignore = ["blender"]
