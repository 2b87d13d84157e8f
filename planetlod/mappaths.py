"""Map references that travel between machines (bpy-free).

A planet names its maps by strings saved in the .blend.  Three kinds:

* bundled data, the maps shipped in the add-on's data/ folder, by a token:
  ``<planet_lod>/earth-topology.png``.  It resolves to the data folder of the
  add-on installed on the machine that reads it, wherever that is (another
  user's home, another Blender version, an extension repository), so no
  per-user absolute path is saved.  Files saved before the token existed
  hold absolute paths ending in ``.../data/<bundled map>``: legacy_bundled()
  recognises them and they resolve like the token.
* ``//`` paths, relative to the .blend (Blender's convention): the caller's
  abspath() makes them absolute.
* absolute paths.  A path that is not there is looked for through path
  mappings (prefix -> prefix, for workers that mount the same storage
  elsewhere), then by its file name in search folders.

resolve() returns the first candidate that exists, else the plain absolute
path, so that a missing map's error message names the path the artist chose.
"""
import os

TOKEN = "<planet_lod>/"

# Environment variables a render worker without saved preferences can set:
# PLANET_LOD_PATH_MAP "FROM=TO" pairs and PLANET_LOD_MAP_FOLDERS folders,
# each list separated by os.pathsep (":" on Linux and macOS, ";" on Windows).
ENV_PATH_MAP = "PLANET_LOD_PATH_MAP"
ENV_MAP_FOLDERS = "PLANET_LOD_MAP_FOLDERS"


def bundled(name):
    """The token of bundled map `name` ("" for none)."""
    return TOKEN + name if name else ""


def token_name(path):
    """The bundled map's file name of a token path, else None."""
    if path and path.startswith(TOKEN) and len(path) > len(TOKEN):
        return path[len(TOKEN):]
    return None


def legacy_bundled(path, bundled_names):
    """The bundled map an absolute path of an older file names
    (``<anything>/data/<bundled map>``), else None."""
    if not path or path.startswith(("//", TOKEN)):
        return None
    parts = path.replace("\\", "/").rstrip("/").split("/")
    if len(parts) >= 2 and parts[-2] == "data" and parts[-1] in bundled_names:
        return parts[-1]
    return None


def parse_path_map(text):
    """[(from, to)] of "FROM=TO" pairs separated by os.pathsep; a pair without
    "=" or with an empty side is a ValueError."""
    pairs = []
    for item in (text or "").split(os.pathsep):
        if not item.strip():
            continue
        if "=" not in item:
            raise ValueError(f"{ENV_PATH_MAP}: {item!r} is not FROM=TO")
        source, target = (side.strip() for side in item.split("=", 1))
        if not source or not target:
            raise ValueError(f"{ENV_PATH_MAP}: {item!r} has an empty side")
        pairs.append((source, target))
    return pairs


def env_settings(environ=None):
    """(path mappings, search folders) from the environment."""
    environ = os.environ if environ is None else environ
    folders = [f for f in environ.get(ENV_MAP_FOLDERS, "").split(os.pathsep) if f.strip()]
    return parse_path_map(environ.get(ENV_PATH_MAP, "")), folders


def _mapped(path, mappings):
    norm = path.replace("\\", "/")
    for source, target in mappings:
        source_n = source.replace("\\", "/").rstrip("/")
        if norm == source_n or norm.startswith(source_n + "/"):
            yield target.rstrip("/\\") + norm[len(source_n):]


def candidates(path, data_path, abspath, bundled_names, mappings=(), folders=()):
    """Where map `path` may be, most likely first (see the module's doc)."""
    name = token_name(path)
    if name is not None:
        yield data_path(name)
        return
    absolute = abspath(path)
    yield absolute
    legacy = legacy_bundled(absolute, bundled_names)
    if legacy is not None:
        yield data_path(legacy)
    yield from _mapped(absolute, mappings)
    base = os.path.basename(absolute.replace("\\", "/"))
    for folder in folders:
        yield os.path.join(folder, base)


def resolve(path, data_path, abspath, bundled_names, mappings=(), folders=(),
            exists=os.path.exists):
    """The file map `path` names on this machine ("" for none): the first
    candidate that exists, else the plain one (which the caller reports as
    missing)."""
    if not path:
        return ""
    found = list(candidates(path, data_path, abspath, bundled_names, mappings, folders))
    for candidate in found:
        if exists(candidate):
            return candidate
    return found[0]
