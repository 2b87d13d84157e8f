"""planetlod.mappaths: bundled maps by token, older files' absolute paths of
bundled maps, path mappings and search folders (bpy-free)."""
import os

import pytest

from planetlod import mappaths

BUNDLED = {"earth-topology.png", "earth-blue-marble.jpg"}


def data_path(name):
    return "/opt/blender/addons/planet_lod/data/" + name


def abspath(path):
    return "/projects/shot/" + path[2:] if path.startswith("//") else path


def resolve(path, existing, mappings=(), folders=()):
    return mappaths.resolve(path, data_path, abspath, BUNDLED, mappings, folders,
                            exists=lambda p: p in existing)


def test_token_resolves_to_this_install():
    token = mappaths.bundled("earth-topology.png")
    assert token == "<planet_lod>/earth-topology.png"
    assert mappaths.token_name(token) == "earth-topology.png"
    assert resolve(token, set()) == data_path("earth-topology.png")
    assert mappaths.bundled("") == ""


def test_older_files_absolute_bundled_paths():
    old = "/home/artist/.config/blender/5.2/extensions/user_default/planet_lod/data/earth-topology.png"
    assert mappaths.legacy_bundled(old, BUNDLED) == "earth-topology.png"
    assert resolve(old, {data_path("earth-topology.png")}) == data_path("earth-topology.png")
    assert resolve(old, {old}) == old  # still there: kept
    assert mappaths.legacy_bundled("/maps/data/mine.png", BUNDLED) is None
    assert mappaths.legacy_bundled("/maps/other/earth-topology.png", BUNDLED) is None


def test_relative_mapping_and_search_folders():
    assert resolve("//maps/a.png", {"/projects/shot/maps/a.png"}) == "/projects/shot/maps/a.png"
    mappings = [("/mnt/projects", "/srv/storage/projects")]
    assert resolve("/mnt/projects/x/a.png", {"/srv/storage/projects/x/a.png"}, mappings) == \
        "/srv/storage/projects/x/a.png"
    # a prefix matches whole folder names only
    assert resolve("/mnt/projects2/a.png", {"/srv/storage/projects2/a.png"}, mappings) == \
        "/mnt/projects2/a.png"
    assert resolve("/gone/a.png", {"/library/a.png"}, folders=["/library"]) == "/library/a.png"
    # nothing found: the path as the artist chose it, for the error message
    assert resolve("//maps/b.png", set(), mappings, ["/library"]) == "/projects/shot/maps/b.png"
    assert resolve("", set()) == ""


def test_environment_settings():
    sep = os.pathsep
    env = {mappaths.ENV_PATH_MAP: f"/mnt/p=/srv/p{sep}/a=/b",
           mappaths.ENV_MAP_FOLDERS: f"/lib1{sep}{sep}/lib2"}
    assert mappaths.env_settings(env) == ([("/mnt/p", "/srv/p"), ("/a", "/b")], ["/lib1", "/lib2"])
    assert mappaths.env_settings({}) == ([], [])
    with pytest.raises(ValueError, match="is not FROM=TO"):
        mappaths.parse_path_map("/mnt/p")
    with pytest.raises(ValueError, match="empty side"):
        mappaths.parse_path_map("/mnt/p=")
