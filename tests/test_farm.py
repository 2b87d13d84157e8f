"""The Flamenco job type (farm/flamenco/planet_lod.js) and what its tasks do.

* `node --test` runs the job type's tests against the stand-in Manager
  (farm/flamenco/harness/): chunks, command lines, dependencies, refusals.
* The compiled jobs then run here, task by task, each command in its own
  Blender process as a worker would run it ({blender} and {blenderArgs}
  expanded, with Flamenco's default `-b -y`): a short flyby split into chunks of 8, 4 and 3 frames gives the
  same CSV rows (sectors, triangles, mesh hash ...) and the same pictures
  for every frame; a saved .blend with a planet rendered with `-s A -e B -a`
  per chunk gives the same pictures whatever the chunks.

Needs node (Debian package nodejs) and Blender; skipped without node.
"""
import csv
import glob
import json
import os
import re
import shlex
import shutil
import struct
import subprocess

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FARM = os.path.join(ROOT, "farm", "flamenco")
JOB_TYPE = os.path.join(FARM, "planet_lod.js")
BLENDER = os.environ.get("BLENDER", shutil.which("blender") or "blender")
NODE = shutil.which("node") or shutil.which("nodejs")
needs_node = pytest.mark.skipif(NODE is None, reason="node is not installed (Debian package nodejs; "
                                                     "bash tools/install_deps.sh tests installs it)")
from farm.flamenco import merge_chunks  # noqa: E402
from farm.flamenco.compile_check import build as flamenco_build  # noqa: E402

# Columns that measure time, not what was rendered.
# How long, and how much incremental work (splits and merges since the frame the
# process rendered before), a frame took: the rest of a row depends on the
# frame alone.
TIMING_COLUMNS = {"refine_us", "mesh_ms", "render_s", "splits", "merges"}
# How a worker sees a written frame (Flamenco's blender-render output parser).
FRAME_SAVED = re.compile(r"(?:^|(?:render\s+\|\s+))Saved: '(.*)'", re.MULTILINE)


@needs_node
def test_job_type_node_tests():
    tests = sorted(glob.glob(os.path.join(FARM, "test", "*.test.js")))
    assert len(tests) >= 2
    proc = subprocess.run([NODE, "--test", "--test-reporter=tap"] + tests, capture_output=True, text=True, timeout=120)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-6000:]
    passed = re.search(r"^# pass (\d+)", output, re.MULTILINE)
    failed = re.search(r"^# fail (\d+)", output, re.MULTILINE)
    assert passed and int(passed.group(1)) >= 20 and failed and failed.group(1) == "0", output[-3000:]


def compile_job(tmp_path, name, settings, created="2001-02-03T04:05:06"):
    submitted = tmp_path / f"{name}.json"
    submitted.write_text(json.dumps({"name": name, "type": "planet-lod", "created": created,
                                     "settings": settings}))
    proc = subprocess.run([NODE, os.path.join(FARM, "harness", "compile.js"), JOB_TYPE, str(submitted)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="module")
def flamenco_compiler(tmp_path_factory):
    """Flamenco's own job compiler (farm/flamenco/compile_check) with the job
    type in the `scripts` folder next to it, as a Manager installs job types."""
    try:
        binary = flamenco_build.build()
    except flamenco_build.BuildUnavailable as e:
        pytest.skip(f"Flamenco's job compiler cannot be built here: {e}")
    manager = tmp_path_factory.mktemp("manager")
    shutil.copy2(binary, manager)
    os.makedirs(manager / "scripts")
    shutil.copy2(JOB_TYPE, manager / "scripts")
    return str(manager / os.path.basename(binary))


def compile_with(command, tmp_path, name, submitted):
    """(exit status, stdout, stderr) of a compiler given a submitted job; the
    Manager's local time is UTC for both."""
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(submitted))
    proc = subprocess.run(command + [str(path)], capture_output=True, text=True, timeout=60,
                          env=dict(os.environ, TZ="UTC"))
    return proc.returncode, proc.stdout, proc.stderr


def without_ids(job):
    """A compiled job with its random UUIDs replaced by task numbers."""
    number = {task["uuid"]: i for i, task in enumerate(job["tasks"])}
    tasks = [dict(task, uuid=number[task["uuid"]],
                  dependencies=[number[d] for d in task["dependencies"]]) for task in job["tasks"]]
    return dict(job, jobID=None, tasks=tasks)


# Submissions both compilers must agree on, refusals included.
FLAMENCO_JOBS = {
    "flyby-defaults": {"source": "flyby", "frames": "1-8", "render_output_root": "/render"},
    "flyby-chunks": {"source": "flyby", "frames": "1-10, 50-60,7", "chunk_size": 4, "preset": "moon",
                     "quality": "final", "path_frames": 60, "resolution": "64x36", "samples": 2,
                     "engine": "BLENDER_EEVEE", "skim_height": 2.5, "threads": 1,
                     "render_output_root": "/render", "planet_lod_root": "/opt/planet_lod"},
    "flyby-path": {"source": "flyby", "frames": "1-6", "chunk_size": 4, "render_output_root": "/render",
                   "path_file": "/paths/alps walk.gpx", "path_frames": 6},
    "bad-path": {"source": "flyby", "frames": "1-6", "render_output_root": "/render", "path_file": 7},
    "blend-runs": {"source": "blendfile", "frames": "1-2,4,9-12", "chunk_size": 3,
                   "render_output_root": "/render", "blendfile": "/shots/shot.blend", "format": "PNG",
                   "scene": "Scene", "addon_module": "bl_ext.user_default.planet_lod",
                   "render_output_path": "/render/shot/{timestamp}"},
    "blend-movie": {"source": "blendfile", "frames": "1-4", "render_output_root": "/render",
                    "blendfile": "/shots/shot.blend", "format": "FFMPEG"},
    "bad-resolution": {"source": "flyby", "frames": "1-8", "render_output_root": "/render",
                       "resolution": "640 by 360"},
    "bad-chunk": {"source": "flyby", "frames": "1-8", "render_output_root": "/render", "chunk_size": 0},
    "bad-frames": {"source": "flyby", "frames": "8-1", "render_output_root": "/render"},
    "no-blendfile": {"source": "blendfile", "frames": "1-8", "render_output_root": "/render"},
}


def test_flamenco_compiler_compiles_the_job_type(flamenco_compiler, tmp_path):
    """Flamenco's own compiler (goja) lists the job type with every setting
    and compiles a flyby job: render tasks by chunk, then the merge task that
    depends on them all, each a blender-render command with {blender}'s
    variables left for the Manager."""
    proc = subprocess.run([flamenco_compiler, "--job-type", "planet-lod"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    job_type = json.loads(proc.stdout)
    assert job_type["name"] == "planet-lod" and job_type["label"] == "Planet LOD" and job_type["etag"]
    keys = [setting["key"] for setting in job_type["settings"]]
    assert {"source", "frames", "chunk_size", "render_output_root", "preset", "blendfile"} <= set(keys)

    status, out, err = compile_with([flamenco_compiler], tmp_path, "fly", {
        "name": "fly", "type": "planet-lod", "created": "2001-02-03T04:05:06",
        "settings": {"source": "flyby", "frames": "1-8", "chunk_size": 3, "render_output_root": "/render"}})
    assert status == 0, err
    job = json.loads(out)
    assert job["settings"]["render_output_path"] == "/render/fly/2001-02-03_040506"
    assert [t["name"] for t in job["tasks"]] == ["render-1-3", "render-4-6", "render-7,8", "merge-chunks"]
    renders = [t["uuid"] for t in job["tasks"][:3]]
    assert job["tasks"][3]["dependencies"] == renders
    command = job["tasks"][0]["commands"][0]
    assert command["name"] == "blender-render" and command["totalStepCount"] == 3
    assert command["parameters"]["exe"] == "{blender}" and command["parameters"]["exeArgs"] == "{blenderArgs}"
    assert "{planet_lod}/tools/flyby.py" in command["parameters"]["args"]


@needs_node
@pytest.mark.parametrize("name", sorted(FLAMENCO_JOBS))
def test_flamenco_compiler_and_stand_in_agree(flamenco_compiler, tmp_path, name):
    """The stand-in Manager that the other farm tests compile with gives the
    job Flamenco's own compiler gives (tasks, commands, dependencies, settings
    as stored), and refuses what it refuses."""
    submitted = {"name": name, "type": "planet-lod", "created": "2001-02-03T04:05:06",
                 "settings": FLAMENCO_JOBS[name]}
    real = compile_with([flamenco_compiler], tmp_path, name, submitted)
    stand_in = compile_with([NODE, os.path.join(FARM, "harness", "compile.js"), JOB_TYPE], tmp_path, name,
                            submitted)
    assert real[0] == stand_in[0], (real, stand_in)
    if real[0] == 0:
        assert without_ids(json.loads(real[1])) == without_ids(json.loads(stand_in[1]))
    else:
        assert name.startswith(("bad", "no", "blend-movie")), real[2]
        # the script's own message, through either engine (goja adds where it was thrown)
        reason = stand_in[2].strip().removeprefix("compile.js: ")
        assert reason and reason in real[2], (real[2], stand_in[2])


def worker_env(tmp_path):
    """Blender with the add-on in a private user-scripts folder and its own
    preferences, as on a worker (which starts Blender without --factory-startup)."""
    scripts = tmp_path / "worker_scripts"
    if not scripts.exists():
        os.makedirs(scripts / "addons")
        os.makedirs(tmp_path / "worker_config")
        os.symlink(os.path.join(ROOT, "addon", "planet_lod"), scripts / "addons" / "planet_lod")
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(scripts)
    env["BLENDER_USER_CONFIG"] = str(tmp_path / "worker_config")
    env.setdefault("PLANET_LOD_NATIVE", ROOT)
    return env


def expand(text):
    """The Manager's variables, as this machine's worker would get them."""
    # Flamenco's default {blenderArgs}: background, scripts of the .blend allowed
    variables = {"blender": BLENDER, "blenderArgs": "-b -y", "planet_lod": ROOT}
    return re.sub(r"{([^}]+)}", lambda m: variables.get(m.group(1), m.group(0)), text)


def run_job(job, env, task_order=None):
    """Runs the tasks (render tasks in task_order, then those that depend on
    them), each blender-render command as a worker's command line; returns
    {task name: [output of each command]}."""
    tasks = {task["uuid"]: task for task in job["tasks"]}
    renders = [t for t in job["tasks"] if not t["dependencies"]]
    later = [t for t in job["tasks"] if t["dependencies"]]
    outputs = {}
    for task in (task_order(renders) if task_order else renders) + later:
        assert all(dep in outputs for dep in (tasks[d]["name"] for d in task["dependencies"]))
        outputs[task["name"]] = []
        for command in task["commands"]:
            assert command["name"] == "blender-render"
            p = command["parameters"]
            line = ([expand(p["exe"])] + shlex.split(expand(p.get("exeArgs", "")))
                    + [expand(a) for a in p["argsBefore"]]
                    + ([expand(p["blendfile"])] if p["blendfile"] else [])
                    + [expand(a) for a in p["args"]])
            proc = subprocess.run(line, env=env, capture_output=True, text=True, timeout=300)
            output = proc.stdout + proc.stderr
            assert proc.returncode == 0, f"{task['name']}: {line}\n{output[-6000:]}"
            if command["totalStepCount"]:  # one picture per step
                assert len(FRAME_SAVED.findall(output)) == command["totalStepCount"], output[-3000:]
            outputs[task["name"]].append(output)
    return outputs


def png_picture(path):
    """The size and pixel data of a PNG (IHDR + IDAT); Blender's text chunks
    carry the date and render time, which differ from run to run."""
    with open(path, "rb") as f:
        data = f.read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    picture, at = [], 8
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        if kind in (b"IHDR", b"IDAT"):
            picture.append(data[at + 8:at + 8 + length])
        at += 12 + length
    return b"".join(picture)


def read_stats(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@needs_node
def test_flyby_job_chunks_give_identical_frames(tmp_path):
    """Frames 1-8 of an 8-frame flyby (orbit, descent, skim) as one task, as
    2x4 and as 3+3+2, render tasks run in reverse order: the merged stats.csv
    rows (all but timings) and every frame's picture are identical."""
    env = worker_env(tmp_path)
    results = {}
    for chunk_size in (8, 4, 3):
        job = compile_job(tmp_path, f"flyby{chunk_size}", {
            "source": "flyby", "frames": "1-8", "chunk_size": chunk_size, "preset": "earth",
            "quality": "draft", "path_frames": 8, "resolution": "64x36", "samples": 1, "threads": 1,
            "render_output_root": str(tmp_path / "render")})
        assert len(job["tasks"]) == -(-8 // chunk_size) + 1
        run_job(job, env, task_order=lambda renders: renders[::-1])
        out = job["settings"]["render_output_path"]
        assert out == str(tmp_path / "render" / f"flyby{chunk_size}" / "2001-02-03_040506")
        rows = read_stats(os.path.join(out, "stats.csv"))
        assert [int(r["frame"]) for r in rows] == list(range(1, 9))
        pictures = {f: png_picture(os.path.join(out, f"frame_{f:04d}.png")) for f in range(1, 9)}
        assert os.path.getsize(os.path.join(out, "contact_sheet.png")) > 0
        chunk_dirs = sorted(os.listdir(os.path.join(out, "chunks")))
        assert len(chunk_dirs) == len(job["tasks"]) - 1
        results[chunk_size] = (rows, pictures, png_picture(os.path.join(out, "contact_sheet.png")))

    def content(rows):
        return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]

    whole_rows, whole_pictures, whole_sheet = results[8]
    for chunk_size in (4, 3):
        rows, pictures, sheet = results[chunk_size]
        assert content(rows) == content(whole_rows), chunk_size
        assert pictures == whole_pictures, chunk_size
        assert sheet == whole_sheet, chunk_size
    # the flyby really changes the LOD and the picture along the way
    assert len({r["mesh_hash"] for r in whole_rows}) >= 6
    assert int(whole_rows[-1]["max_level"]) > int(whole_rows[0]["max_level"])
    assert len(set(whole_pictures.values())) == 8


@needs_node
def test_blendfile_job_chunks_give_identical_frames(tmp_path):
    """A saved .blend with a planet and its flyby camera, submitted as Flamenco's
    add-on would (its `eval` settings evaluated in that Blender scene), renders
    frames 1-2 and 4 as one task (two runs in one Blender) and as three tasks:
    the same pictures, and each frame shows its own LOD.  A .blend whose height
    map is not on the worker fails its task."""
    env = worker_env(tmp_path)
    job_type = tmp_path / "job_type.json"
    proc = subprocess.run([NODE, os.path.join(FARM, "harness", "compile.js"), "--job-type", JOB_TYPE],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    job_type.write_text(proc.stdout)
    blend, evaluated = tmp_path / "shot.blend", tmp_path / "evaluated.json"
    moved_map = tmp_path / "moved_map.blend"
    proc = subprocess.run([BLENDER, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                           os.path.join(ROOT, "tests", "blender", "farm_planet_blend.py"), "--",
                           str(blend), str(job_type), str(evaluated), str(moved_map)],
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-6000:]
    values = json.loads(evaluated.read_text())
    assert values["frames"] == "1-8" and values["format"] == "PNG" and values["scene"] == "Scene"
    assert values["render_output_path"] == "/render/shot/{timestamp}"

    pictures = {}
    for chunk_size in (3, 1):
        output_root = tmp_path / f"render{chunk_size}"
        job = compile_job(tmp_path, "shot", {
            "source": "blendfile", "frames": "1-2,4", "chunk_size": chunk_size,
            "render_output_root": str(output_root), "blendfile": str(blend),
            "format": values["format"], "scene": values["scene"],
            "render_output_path": str(output_root / "shot" / "{timestamp}")})
        assert len(job["tasks"]) == 3 // chunk_size + 1  # and merge-stats
        run_job(job, env)
        out = job["settings"]["render_output_path"]
        assert sorted(os.listdir(out)) == ["frame_000001.png", "frame_000002.png", "frame_000004.png"]
        pictures[chunk_size] = {f: png_picture(os.path.join(out, f)) for f in os.listdir(out)}
    assert pictures[3] == pictures[1]
    assert len(set(pictures[3].values())) == 3

    # A planet whose height map the worker cannot read fails its task with the
    # reason, instead of rendering the mesh saved in the .blend.
    job = compile_job(tmp_path, "moved", {
        "source": "blendfile", "frames": "1", "render_output_root": str(tmp_path / "moved"),
        "blendfile": str(moved_map), "format": "PNG", "scene": "Scene"})
    with pytest.raises(AssertionError, match=r"planet_lod: Earth: height map not found: .*gone"):
        run_job(job, env)
    assert not (tmp_path / "moved").exists()


# A walk along a valley: waypoints 300 m and then 50 m above the ground.
WAYPOINTS = os.path.join(ROOT, "farm", "examples", "valley-walk.csv")

@needs_node
def test_flyby_job_on_a_path_file(tmp_path):
    """A flyby job with `path_file`, in two chunks: the workers fly the
    waypoints (the camera near their heights above the ground at their
    frames); a frame outside the path fails its task."""
    env = worker_env(tmp_path)
    path_file = tmp_path / "paths" / "valley walk.csv"
    os.makedirs(path_file.parent)
    shutil.copy(WAYPOINTS, path_file)
    job = compile_job(tmp_path, "walk", {
        "source": "flyby", "frames": "1-4", "chunk_size": 2, "path_file": str(path_file),
        "quality": "draft", "resolution": "48x27", "samples": 1, "threads": 1,
        "render_output_root": str(tmp_path / "render")})
    run_job(job, env)
    out = job["settings"]["render_output_path"]
    rows = read_stats(os.path.join(out, "stats.csv"))
    pictures = [png_picture(os.path.join(out, f"frame_{f:04d}.png")) for f in range(1, 5)]
    assert [int(r["frame"]) for r in rows] == [1, 2, 3, 4]
    heights = [float(r["camera_altitude_m"]) - float(r["camera_ground_m"]) for r in rows]
    # the path follows a smoothed ground: the height over the ground right under
    # the camera differs from the waypoint's by tens of metres in the Alps
    assert 250.0 < heights[0] < 350.0 and 20.0 < heights[3] < 100.0, heights
    assert len(set(pictures)) == 4

    job = compile_job(tmp_path, "beyond", {
        "source": "flyby", "frames": "3-6", "path_file": str(path_file), "quality": "draft",
        "resolution": "48x27", "samples": 1, "render_output_root": str(tmp_path / "beyond")})
    with pytest.raises(AssertionError, match=r"frames 3-6 are outside the path \(frames 1-4\)"):
        run_job(job, env)


def test_merge_frame_stats(tmp_path):
    """Per-frame stats files (as headless renders through a planet_lod_geo
    camera write them) merge into one stats.csv in frame order; a re-written
    frame replaces its row; missing and unasked-for frames, and files that are
    not a frame's stats, are refused before stats.csv is written."""
    from planetlod import report
    assert report.merge_frame_stats(str(tmp_path)) == 0  # no stats: nothing to merge
    assert not (tmp_path / "stats.csv").exists()
    for frame in (12, 9, 10):
        report.write_frame_stats(str(tmp_path), {"frame": frame, "triangles": frame, "mesh_hash": "old"})
    report.write_frame_stats(str(tmp_path), {"frame": 10, "triangles": 100, "mesh_hash": "new"})
    assert sorted(os.listdir(tmp_path / report.FRAME_STATS_FOLDER)) == \
        ["frame_000009.csv", "frame_000010.csv", "frame_000012.csv"]
    assert report.merge_frame_stats(str(tmp_path), "9-10,12") == 3
    rows = read_stats(tmp_path / "stats.csv")
    assert [(r["frame"], r["triangles"], r["mesh_hash"]) for r in rows] == \
        [("9", "9", "old"), ("10", "100", "new"), ("12", "12", "old")]
    assert list(rows[0]) == list(report.CSV_FIELDS)
    assert report.parse_frame_list("1-3,7, 10..12,20-24:2") == [1, 2, 3, 7, 10, 11, 12, 20, 22, 24]

    def refused(frames, pattern):
        (tmp_path / "stats.csv").unlink()
        with pytest.raises(ValueError, match=pattern):
            report.merge_frame_stats(str(tmp_path), frames)
        assert not (tmp_path / "stats.csv").exists()
        (tmp_path / "stats.csv").write_text("")

    (tmp_path / "stats.csv").write_text("")
    refused("9-12", r"frames without stats in .*: \[11\]")
    refused([9, 10], r"stats of frames not asked for in .*: \[12\]")
    refused("9-", "bad frame range")
    (tmp_path / report.FRAME_STATS_FOLDER / "frame_000011.csv").write_text("frame\n11\n")
    refused("9-12", "frame_000011.csv: not a frame's stats")


def _chunk(folder, header, rows, frames_with_pictures):
    os.makedirs(folder)
    with open(os.path.join(folder, "stats.csv"), "w") as f:
        f.write("\n".join([header] + rows) + "\n")
    for frame in frames_with_pictures:
        with open(os.path.join(folder, f"frame_{frame:04d}.png"), "wb") as f:
            f.write(b"png %d" % frame)


def test_merge_chunks(tmp_path):
    """The merge task: frames moved, rows in frame order unchanged, a second run
    gives the same; missing, doubled, unasked-for frames and mismatched columns
    are refused before anything moves."""
    header = "frame,triangles,mesh_hash"
    chunks, out = tmp_path / "out" / "chunks", tmp_path / "out"
    _chunk(chunks / "frames-0004-0005", header, ["4,40,d", "5,50,e"], [4, 5])
    _chunk(chunks / "frames-0001-0003", header, ["1,10,a", "2,20,b", "3,30,c"], [1, 2, 3])
    assert merge_chunks.parse_frames("1-3,4..5") == [1, 2, 3, 4, 5]
    for _ in range(2):
        paths = merge_chunks.merge(str(chunks), [1, 2, 3, 4, 5], str(out))
        assert [os.path.basename(p) for p in paths] == [f"frame_{f:04d}.png" for f in range(1, 6)]
        assert (out / "stats.csv").read_text() == \
            "frame,triangles,mesh_hash\n1,10,a\n2,20,b\n3,30,c\n4,40,d\n5,50,e\n"
        assert (out / "frame_0004.png").read_bytes() == b"png 4"
    assert not (chunks / "frames-0001-0003" / "frame_0001.png").exists()

    def refused(frames, pattern):
        with pytest.raises(merge_chunks.MergeError, match=pattern):
            merge_chunks.merge(str(chunks), frames, str(tmp_path / "elsewhere"))
        assert not (tmp_path / "elsewhere").exists()

    refused([1, 2, 3, 4, 5, 6], r"frames without a stats row: \[6\]")
    refused([1, 2, 3, 4], r"not asked for: \[5\]")
    _chunk(chunks / "frames-0005-0006", header, ["5,50,e", "6,60,f"], [5, 6])
    refused([1, 2, 3, 4, 5, 6], "frame 5 is in two chunks")
    shutil.rmtree(chunks / "frames-0005-0006")
    _chunk(chunks / "frames-0006-0006", "frame,vertices,mesh_hash", ["6,60,f"], [6])
    refused([1, 2, 3, 4, 5, 6], "other columns")
    shutil.rmtree(chunks / "frames-0006-0006")
    _chunk(chunks / "frames-0006-0006", header, ["6,60,f"], [])
    (out / "frame_0001.png").unlink()  # neither in its chunk nor moved: lost
    refused([1, 2, 3, 4, 5, 6], "no picture")
    with pytest.raises(merge_chunks.MergeError, match="bad frame range"):
        merge_chunks.parse_frames("1-x")
