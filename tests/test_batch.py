"""Headless renders as a farm worker runs them (`blender -b -y FILE.blend ...
-a`, Flamenco's command line; tools/flyby.py): a planet that cannot be built
stops the render with the reason and a non-zero exit, and writes no frame;
tools/flyby.py finds the add-on whatever module name Blender gave it.

Needs Debian's Blender ($BLENDER); the extension test needs a bpy wheel of
4.2 or later (tools/blender_versions.py).
"""
import glob
import os
import shutil
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")
MAKE_BLEND = os.path.join(ROOT, "tests", "blender", "batch_planet_blend.py")
FLYBY = os.path.join(ROOT, "tools", "flyby.py")

from tools import blender_versions  # noqa: E402


def user_env(tmp_path, name="user"):
    """A worker's Blender: the add-on linked into its own user-scripts folder."""
    scripts = tmp_path / name / "scripts"
    os.makedirs(scripts / "addons")
    os.makedirs(tmp_path / name / "config")
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"), scripts / "addons" / "planet_lod")
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(scripts)
    env["BLENDER_USER_CONFIG"] = str(tmp_path / name / "config")
    env.setdefault("PLANET_LOD_NATIVE", ROOT)
    return env


def blender(args, env, timeout=300):
    proc = subprocess.run([BLENDER] + args, env=env, capture_output=True, text=True,
                          timeout=timeout)
    return proc.returncode, proc.stdout + proc.stderr


def make_blend(tmp_path, env, blend, preset="earth", heightmap=None):
    os.makedirs(blend.parent, exist_ok=True)
    rc, output = blender(["-b", "--factory-startup", "--python-exit-code", "1", "--python",
                          MAKE_BLEND, "--", str(blend), preset] + ([heightmap] if heightmap else []),
                         env)
    assert rc == 0 and "PLOD-BATCH saved" in output, output[-4000:]


def render_animation(blend, out, env, frames=(1, 2)):
    """Flamenco's worker command line for a .blend: -b -y FILE ... -a."""
    return blender(["-b", "-y", "--addons", "planet_lod", str(blend), "--render-output",
                    str(out / "frame_####"), "-s", str(frames[0]), "-e", str(frames[1]), "-a"],
                   env)


def test_missing_map_stops_blend_render(tmp_path):
    """A .blend whose height map is not there: `-a` exits non-zero, names the
    planet and the map, and writes no frame; with the map back it renders."""
    env = user_env(tmp_path)
    maps = tmp_path / "shot" / "maps"
    os.makedirs(maps)
    shutil.copy(os.path.join(ROOT, "data", "earth-topology.png"), maps / "earth.png")
    blend = tmp_path / "shot" / "shot.blend"
    make_blend(tmp_path, env, blend, heightmap="//maps/earth.png")
    hidden = tmp_path / "shot" / "hidden.png"
    os.rename(maps / "earth.png", hidden)
    rc, output = render_animation(blend, tmp_path / "out", env)
    assert rc != 0, output[-4000:]
    assert "planet_lod: cannot render frame 1: Earth: height map not found" in output, \
        output[-4000:]
    assert glob.glob(str(tmp_path / "out" / "*")) == []
    os.rename(hidden, maps / "earth.png")
    rc, output = render_animation(blend, tmp_path / "out", env)
    assert rc == 0, output[-4000:]
    assert sorted(os.listdir(tmp_path / "out")) == ["frame_0001.png", "frame_0002.png"]


def _stats_without_timings(path):
    import csv
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k not in ("refine_us", "mesh_ms", "render_s",
                                                          "splits", "merges")}
                for row in csv.DictReader(f)]


def test_geo_camera_stats_from_parallel_chunks(tmp_path):
    """`-a` through a keyframed planet_lod_geo camera: every frame writes its own
    stats file, so two chunks rendering into one folder at the same time lose
    none; merging them gives the stats.csv of one process rendering all the
    frames (but for timings), a row per frame in frame order."""
    env = user_env(tmp_path)
    blend = tmp_path / "shot" / "geo.blend"
    make_blend(tmp_path, dict(env, PLOD_GEO_CAMERA="1"), blend)

    def command(out, first, last):
        return [BLENDER, "-b", "-y", "--addons", "planet_lod", str(blend), "--render-output",
                str(out / "frame_####"), "-s", str(first), "-e", str(last), "-a"]

    def merge(out, frames):
        return blender(["-b", "-y", "--addons", "planet_lod", "--python-exit-code", "1",
                        "--python-expr", "import planet_lod; "
                        f"print('PLOD rows', planet_lod.merge_frame_stats({str(out)!r}, {frames!r}))"],
                       env)

    chunks = tmp_path / "chunks"
    running = [subprocess.Popen(command(chunks, first, last), env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True) for first, last in ((1, 2), (3, 4))]
    for proc in running:
        output = proc.communicate(timeout=300)[0]
        assert proc.returncode == 0, output[-4000:]
    assert sorted(os.listdir(chunks / "planet_lod_stats")) == [f"frame_{f:06d}.csv" for f in range(1, 5)]
    rc, output = merge(chunks, "1-4")
    assert rc == 0 and "PLOD rows 4" in output, output[-4000:]

    whole = tmp_path / "whole"
    rc, output = blender(command(whole, 1, 4)[1:], env)
    assert rc == 0, output[-4000:]
    rc, output = merge(whole, "1-4")
    assert rc == 0 and "PLOD rows 4" in output, output[-4000:]

    rows = _stats_without_timings(chunks / "stats.csv")
    assert rows == _stats_without_timings(whole / "stats.csv")
    assert [int(r["frame"]) for r in rows] == [1, 2, 3, 4]
    for row in rows:  # the keyframed 2 km above the ground
        height = float(row["camera_altitude_m"]) - float(row["camera_ground_m"])
        assert abs(height - 2000.0) < 1.0, row
        assert int(row["triangles"]) > 0
    assert len({r["camera_ground_m"] for r in rows}) == 4  # it moved over the ground

    # a frame asked for that no chunk rendered: the merge fails with its number
    rc, output = merge(chunks, "1-5")
    assert rc != 0 and "frames without stats" in output and "[5]" in output, output[-4000:]


def test_flyby_without_maps_fails(tmp_path):
    """tools/flyby.py with an add-on install that lacks its maps: a non-zero
    exit with the reason, no frame."""
    addon = tmp_path / "scripts" / "addons" / "planet_lod"
    shutil.copytree(os.path.join(ROOT, "addon", "planet_lod"), addon,
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(tmp_path / "scripts")
    env["PLANET_LOD_NATIVE"] = ROOT  # the package, but not the repository's data/
    out = tmp_path / "flyby"
    rc, output = blender(["-b", "--factory-startup", "--python-exit-code", "1", "--python",
                          FLYBY, "--", "--frames", "1-2", "--path-frames", "4",
                          "--resolution", "32x18", "--samples", "1", "--out",
                          str(out)], env)
    assert rc != 0, output[-4000:]
    assert "map not found" in output, output[-4000:]
    assert glob.glob(str(out / "frame_*")) == []


def _oldest_bpy():
    installed = [(v, python) for v, python in blender_versions.installed()]
    return installed[0] if installed else (None, None)


def test_flyby_finds_extension(tmp_path):
    """The add-on installed as an extension (bl_ext.user_default.planet_lod,
    Blender 4.2+): tools/flyby.py finds it and renders."""
    label, python = _oldest_bpy()
    if python is None:
        pytest.skip("no bpy wheel installed (python3 tools/blender_versions.py install)")
    env = dict(os.environ)
    for var, sub in (("BLENDER_USER_SCRIPTS", "scripts"), ("BLENDER_USER_CONFIG", "config"),
                     ("BLENDER_USER_EXTENSIONS", "extensions")):
        env[var] = str(tmp_path / sub)
        os.makedirs(env[var])
    os.makedirs(tmp_path / "extensions" / "user_default")
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"),
               tmp_path / "extensions" / "user_default" / "planet_lod")
    env["PLANET_LOD_NATIVE"] = ROOT
    env.pop("PYTHONPATH", None)
    out = tmp_path / "flyby"
    proc = subprocess.run([python, blender_versions.RUNNER, FLYBY, "--", "--frames", "2-3",
                           "--path-frames", "4", "--resolution", "32x18", "--quality", "draft",
                           "--samples", "1", "--out", str(out)],
                          env=env, capture_output=True, text=True, timeout=300)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-4000:]
    assert "bl_ext.user_default.planet_lod" in output, output[-4000:]
    assert sorted(p for p in os.listdir(out) if p.startswith("frame_")) == \
        ["frame_0002.png", "frame_0003.png"]


def png_picture(path):
    """A PNG's size and pixels (IHDR + IDAT), without the text chunks that
    carry the render time."""
    import struct
    with open(path, "rb") as f:
        data = f.read()
    picture, at = [], 8
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        if kind in (b"IHDR", b"IDAT"):
            picture.append(data[at + 8:at + 8 + length])
        at += 12 + length
    return b"".join(picture)


def installed_env(tmp_path, name):
    """Another user's Blender: its own home, user-scripts folder and a copy of
    the add-on with its maps (as tools/install_addon.py installs it)."""
    home = tmp_path / name
    addon = home / "scripts" / "addons" / "planet_lod"
    shutil.copytree(os.path.join(ROOT, "addon", "planet_lod"), addon,
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(os.path.join(ROOT, "data"), addon / "data")
    os.makedirs(home / "config")
    env = dict(os.environ)
    env.update(HOME=str(home), BLENDER_USER_SCRIPTS=str(home / "scripts"),
               BLENDER_USER_CONFIG=str(home / "config"), PLANET_LOD_NATIVE=ROOT)
    return env, home


@pytest.mark.parametrize("preset", ["earth", "moon", "mars", "asteroid"])
def test_preset_blend_travels(tmp_path, preset):
    """A .blend saved from a preset names no path of the add-on install that
    made it (nor its data folder), and renders the same frames under another home and another
    add-on install after the first one is gone."""
    env_a, home_a = installed_env(tmp_path, "artist")
    blend = tmp_path / "shot" / "shot.blend"
    make_blend(tmp_path, env_a, blend, preset=preset)
    saved = blend.read_bytes()
    assert str(home_a / "scripts").encode() not in saved and b"planet_lod/data" not in saved
    rc, output = render_animation(blend, tmp_path / "out_a", env_a)
    assert rc == 0, output[-4000:]
    shutil.rmtree(home_a)
    env_b, _home_b = installed_env(tmp_path, "worker")
    rc, output = render_animation(blend, tmp_path / "out_b", env_b)
    assert rc == 0, output[-4000:]
    for frame in ("frame_0001.png", "frame_0002.png"):
        assert png_picture(tmp_path / "out_a" / frame) == png_picture(tmp_path / "out_b" / frame)


def test_relative_user_map_follows_the_folder(tmp_path):
    """A .blend whose height map is //maps/earth.png renders the same after its
    folder moves."""
    env = user_env(tmp_path)
    shot = tmp_path / "shot"
    os.makedirs(shot / "maps")
    shutil.copy(os.path.join(ROOT, "data", "earth-topology.png"), shot / "maps" / "earth.png")
    make_blend(tmp_path, env, shot / "shot.blend", heightmap="//maps/earth.png")
    rc, output = render_animation(shot / "shot.blend", tmp_path / "before", env, frames=(3, 3))
    assert rc == 0, output[-4000:]
    moved = tmp_path / "elsewhere" / "shot moved"
    os.makedirs(moved.parent)
    os.rename(shot, moved)
    rc, output = render_animation(moved / "shot.blend", tmp_path / "after", env, frames=(3, 3))
    assert rc == 0, output[-4000:]
    assert png_picture(tmp_path / "before" / "frame_0003.png") == \
        png_picture(tmp_path / "after" / "frame_0003.png")


def flyby(args, env, out):
    return blender(["-b", "--factory-startup", "--python-exit-code", "1", "--python", FLYBY, "--",
                    "--resolution", "32x18", "--samples", "1", "--quality", "draft",
                    "--out", str(out)] + args, env)


WAYPOINTS = ["--waypoint", "1,7.0,46.0,6000,90,-20", "--waypoint", "3,7.03,46.01,3500,95,-12",
             "--waypoint", "4,7.04,46.01,3200,97,-10", "--altitude-reference", "sea"]


def test_flyby_on_waypoints(tmp_path):
    """tools/flyby.py flies waypoints given on the command line: every frame gets
    its stats row and the contact sheet; a chunk renders the whole run's
    pictures; frames outside the path and bad path files are refused before
    any frame is written."""
    env = user_env(tmp_path)
    rc, output = flyby(WAYPOINTS, env, tmp_path / "whole")
    assert rc == 0, output[-4000:]
    with open(tmp_path / "whole" / "stats.csv") as f:
        rows = f.read().splitlines()
    assert rows[0].startswith("frame,") and [r.split(",")[0] for r in rows[1:]] == \
        ["1", "2", "3", "4"]
    assert (tmp_path / "whole" / "contact_sheet.png").stat().st_size > 0
    rc, output = flyby(WAYPOINTS + ["--frames", "3-4"], env, tmp_path / "part")
    assert rc == 0, output[-4000:]
    for frame in ("frame_0003.png", "frame_0004.png"):
        assert png_picture(tmp_path / "whole" / frame) == png_picture(tmp_path / "part" / frame)

    rc, output = flyby(WAYPOINTS + ["--frames", "4-5"], env, tmp_path / "outside")
    assert rc != 0 and "frames 4-5 are outside the path (frames 1-4)" in output, output[-4000:]
    assert not glob.glob(str(tmp_path / "outside" / "frame_*"))
    bad = tmp_path / "bad.gpx"
    bad.write_text("<gpx><trk><trkseg><trkpt lat='46' lon='7'/></trkseg></trk></gpx>")
    rc, output = flyby(["--path", str(bad)], env, tmp_path / "bad")
    assert rc != 0 and "bad.gpx: a track needs at least 2 points, found 1" in output, \
        output[-4000:]
    assert not glob.glob(str(tmp_path / "bad" / "frame_*"))


def test_older_files_and_moved_map_folders(tmp_path):
    """A .blend saved with an absolute path into the add-on's data folder (as
    older versions saved bundled maps) renders under another install once
    that one is gone; a map whose folder moved is found through a path
    mapping or a map search folder from the worker's environment, and is
    not found without them."""
    env_a, home_a = installed_env(tmp_path, "artist")
    old = tmp_path / "old" / "old.blend"
    absolute = str(home_a / "scripts" / "addons" / "planet_lod" / "data" / "earth-topology.png")
    make_blend(tmp_path, dict(env_a, PLOD_SAVE_AS_OLDER="1"), old, heightmap=absolute)
    assert absolute.encode() in old.read_bytes()
    shutil.rmtree(home_a)
    env_b, _home_b = installed_env(tmp_path, "worker")
    rc, output = render_animation(old, tmp_path / "old_out", env_b, frames=(1, 1))
    assert rc == 0, output[-4000:]

    maps = tmp_path / "mnt" / "projects" / "maps"
    os.makedirs(maps)
    shutil.copy(os.path.join(ROOT, "data", "earth-topology.png"), maps / "earth.png")
    shot = tmp_path / "shot" / "shot.blend"
    make_blend(tmp_path, env_b, shot, heightmap=str(maps / "earth.png"))
    os.makedirs(tmp_path / "srv")
    os.rename(tmp_path / "mnt" / "projects", tmp_path / "srv" / "projects")
    rc, output = render_animation(shot, tmp_path / "lost", env_b, frames=(1, 1))
    assert rc != 0 and "height map not found" in output, output[-4000:]
    mapped = dict(env_b, PLANET_LOD_PATH_MAP=f"{tmp_path / 'mnt'}={tmp_path / 'srv'}")
    rc, output = render_animation(shot, tmp_path / "mapped", mapped, frames=(1, 1))
    assert rc == 0, output[-4000:]
    searched = dict(env_b, PLANET_LOD_MAP_FOLDERS=str(tmp_path / "srv" / "projects" / "maps"))
    rc, output = render_animation(shot, tmp_path / "searched", searched, frames=(1, 1))
    assert rc == 0, output[-4000:]
