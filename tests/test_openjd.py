"""The Open Job Description templates (farm/openjd/) run by OpenJD's own
runtime (openjd-cli, openjd-sessions: tools/openjd_env.py installs them),
task by task, each chunk in its own Blender as a worker would run it
(`blender -b -y ...`):

* a flyby split into chunks of 4 and 3 frames gives the files (pictures,
  byte for byte) and stats rows of the run in one chunk;
* a flyby on a waypoints file (PathFile) flies it, and refuses frames beyond it;
* a .blend rendered in chunks of 3 and 1 frames gives the same pictures
  (pixels: Blender writes Cycles' render timings into the .blend's PNGs), and
  through its planet_lod_geo camera the same stats.csv (the MergeStats step);
* a .blend whose map the worker cannot find fails its task with the reason
  and writes no frame.

Skipped, with the reason, where the OpenJD runtime is not installed.
"""
import csv
import os
import shutil
import subprocess

import pytest

from tools import openjd_env

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TEMPLATES = os.path.join(ROOT, "farm", "openjd")
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")
OPENJD = openjd_env.openjd()
needs_openjd = pytest.mark.skipif(
    OPENJD is None, reason="the OpenJD runtime is not installed "
                           "(python3 -m tools.openjd_env install; tools/run_tests.sh runs it)")
# Columns that measure time or incremental work since the process's previous frame.
TIMING_COLUMNS = {"refine_us", "mesh_ms", "render_s", "splits", "merges"}


def worker_env(tmp_path):
    scripts = tmp_path / "worker" / "scripts"
    os.makedirs(scripts / "addons")
    os.makedirs(tmp_path / "worker" / "config")
    os.symlink(os.path.join(ROOT, "addon", "planet_lod"), scripts / "addons" / "planet_lod")
    env = dict(os.environ)
    env.update(BLENDER_USER_SCRIPTS=str(scripts), BLENDER_USER_CONFIG=str(tmp_path / "worker" / "config"),
               PLANET_LOD_NATIVE=ROOT)
    return env


def openjd_run(template, step, params, env, dependencies=False):
    args = [OPENJD, "run", os.path.join(TEMPLATES, template), "--step", step,
            "--run-dependencies" if dependencies else "--no-run-dependencies"]
    for key, value in params.items():
        args += ["-p", f"{key}={value}"]
    proc = subprocess.run(args, env=env, capture_output=True, text=True, timeout=900)
    return proc.returncode, proc.stdout + proc.stderr


def files(folder):
    return {name: open(os.path.join(folder, name), "rb").read()
            for name in sorted(os.listdir(folder)) if name.startswith("frame_")}


def pictures(folder):
    """Each frame's size and pixels (IHDR + IDAT): a .blend's Cycles frames
    carry the render's timings in text chunks."""
    import struct
    found = {}
    for name, data in files(folder).items():
        parts, at = [], 8
        while at < len(data):
            length, kind = struct.unpack(">I4s", data[at:at + 8])
            if kind in (b"IHDR", b"IDAT"):
                parts.append(data[at + 8:at + 8 + length])
            at += 12 + length
        found[name] = b"".join(parts)
    return found


def stats(folder):
    with open(os.path.join(folder, "stats.csv"), newline="") as f:
        return [{k: v for k, v in row.items() if k not in TIMING_COLUMNS}
                for row in csv.DictReader(f)]


@needs_openjd
def test_templates_pass_openjd_checks():
    for template in ("planet_lod_flyby.yaml", "planet_lod_blend.yaml"):
        proc = subprocess.run([OPENJD, "check", os.path.join(TEMPLATES, template)],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0 and "passes validation" in proc.stdout, proc.stdout + proc.stderr


@needs_openjd
def test_flyby_job_chunks_give_identical_files(tmp_path):
    env = worker_env(tmp_path)
    results = {}
    for chunk_size in (8, 4, 3):
        out = tmp_path / f"flyby{chunk_size}"
        rc, output = openjd_run("planet_lod_flyby.yaml", "Merge", {
            "PlanetLodRoot": ROOT, "OutputDir": str(out), "Blender": BLENDER, "Frames": "1-8",
            "ChunkSize": chunk_size, "PathFrames": 8, "Resolution": "48x27", "Samples": 1,
            "Quality": "draft", "Threads": 1}, env, dependencies=True)
        assert rc == 0, output[-6000:]
        assert len(os.listdir(out / "chunks")) == -(-8 // chunk_size)
        assert (out / "contact_sheet.png").stat().st_size > 0
        results[chunk_size] = (files(out), stats(out))
    whole_files, whole_stats = results[8]
    assert sorted(whole_files) == [f"frame_{f:04d}.png" for f in range(1, 9)]
    assert len(set(whole_files.values())) == 8
    for chunk_size in (4, 3):
        assert results[chunk_size][0] == whole_files, chunk_size
        assert results[chunk_size][1] == whole_stats, chunk_size


@needs_openjd
def test_flyby_job_on_a_path_file(tmp_path):
    """PathFile: the chunks fly the waypoints of a file (frames of one path
    alike whatever the chunks), and a frame beyond it fails the job."""
    env = worker_env(tmp_path)
    path_file = tmp_path / "paths" / "valley walk.csv"
    os.makedirs(path_file.parent)
    shutil.copy(os.path.join(ROOT, "farm", "examples", "valley-walk.csv"), path_file)
    params = {"PlanetLodRoot": ROOT, "Blender": BLENDER, "PathFile": str(path_file), "Resolution": "48x27",
              "Samples": 1, "Quality": "draft", "Threads": 1}
    out = tmp_path / "walk"
    rc, output = openjd_run("planet_lod_flyby.yaml", "Merge", dict(
        params, OutputDir=str(out), Frames="1-4", ChunkSize=2), env, dependencies=True)
    assert rc == 0, output[-6000:]
    rows = stats(out)
    assert [int(r["frame"]) for r in rows] == [1, 2, 3, 4]
    heights = [float(r["camera_altitude_m"]) - float(r["camera_ground_m"]) for r in rows]
    # near the waypoints' 300 m and 50 m above the ground (the path follows a smoothed ground)
    assert 250.0 < heights[0] < 350.0 and 20.0 < heights[3] < 100.0, heights
    assert len(set(files(out).values())) == 4

    rc, output = openjd_run("planet_lod_flyby.yaml", "Render", dict(
        params, OutputDir=str(tmp_path / "beyond"), Frames="3-6", ChunkSize=4), env)
    assert rc != 0 and "frames 3-6 are outside the path (frames 1-4)" in output, output[-6000:]


@needs_openjd
def test_blend_job_chunks_and_a_missing_map(tmp_path):
    env = worker_env(tmp_path)
    shot = tmp_path / "shot"
    os.makedirs(shot / "maps")
    shutil.copy(os.path.join(ROOT, "data", "earth-topology.png"), shot / "maps" / "earth.png")
    proc = subprocess.run([BLENDER, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                           os.path.join(ROOT, "tests", "blender", "batch_planet_blend.py"), "--",
                           str(shot / "shot.blend"), "earth", "//maps/earth.png"],
                          env=dict(env, PLOD_GEO_CAMERA="1"), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-4000:]
    rendered, merged = {}, {}
    for chunk_size in (3, 1):
        out = tmp_path / f"blend{chunk_size}"
        rc, output = openjd_run("planet_lod_blend.yaml", "Render", {
            "BlendFile": str(shot / "shot.blend"), "OutputDir": str(out), "Blender": BLENDER,
            "Frames": "1-3", "ChunkSize": chunk_size}, env)
        assert rc == 0, output[-6000:]
        rendered[chunk_size] = pictures(out)
        # the frames' own stats files, from every chunk, into one stats.csv
        rc, output = openjd_run("planet_lod_blend.yaml", "MergeStats", {
            "BlendFile": str(shot / "shot.blend"), "OutputDir": str(out), "Blender": BLENDER,
            "Frames": "1-3"}, env)
        assert rc == 0 and "planet_lod: stats.csv rows: 3" in output, output[-6000:]
        merged[chunk_size] = stats(out)
    assert sorted(rendered[3]) == ["frame_000001.png", "frame_000002.png", "frame_000003.png"]
    assert rendered[1] == rendered[3]
    assert len(set(rendered[3].values())) == 3
    assert [int(r["frame"]) for r in merged[3]] == [1, 2, 3]
    assert merged[1] == merged[3]

    os.rename(shot / "maps", shot / "elsewhere")
    out = tmp_path / "missing"
    rc, output = openjd_run("planet_lod_blend.yaml", "Render", {
        "BlendFile": str(shot / "shot.blend"), "OutputDir": str(out), "Blender": BLENDER,
        "Frames": "1-2", "ChunkSize": 2}, env)
    assert rc != 0, output[-6000:]
    assert "planet_lod: cannot render frame 1: Earth: height map not found" in output, output[-6000:]
    assert not out.exists() or not os.listdir(out)
