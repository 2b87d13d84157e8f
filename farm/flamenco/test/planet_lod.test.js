// The planet-lod job type, compiled by the stand-in Manager: every frame in
// exactly one task, chunks of the chosen size, the right Blender command
// lines, the merge after every render, and clear refusals of bad settings.
"use strict";

const assert = require("node:assert/strict");
const nodePath = require("node:path");
const test = require("node:test");

const flamenco = require("../harness/flamenco.js");

const JOB_TYPE_FILE = nodePath.join(__dirname, "..", "planet_lod.js");
const loaded = flamenco.loadJobType(JOB_TYPE_FILE);
const CREATED = "2001-02-03T04:05:06";
const STAMP = flamenco.formatTimestampLocal(new Date(CREATED));

function flybyJob(settings) {
    return loaded.compile({
        name: "earth", type: "planet-lod", created: CREATED,
        settings: Object.assign({ source: "flyby", frames: "1-120", chunk_size: 10,
                                  render_output_root: "/render" }, settings),
    });
}

function blendJob(settings) {
    return loaded.compile({
        name: "shot", type: "planet-lod", created: CREATED,
        settings: Object.assign({ source: "blendfile", frames: "1-20", chunk_size: 5,
                                  render_output_root: "/render", blendfile: "/jobs/shot.blend",
                                  format: "PNG", scene: "Scene" }, settings),
    });
}

function argValue(args, name) {
    const i = args.indexOf(name);
    assert.ok(i >= 0 && i + 1 < args.length, `${name} in ${args}`);
    return args[i + 1];
}

function range(first, last) {
    return Array.from({ length: last - first + 1 }, (_, i) => first + i);
}

// The frames each render task renders, from its command lines.
function renderedFrames(job, source) {
    const byTask = [];
    for (const task of job.tasks.filter((t) => t.name.startsWith("render-"))) {
        const frames = [];
        for (const command of task.commands) {
            const args = command.parameters.args;
            if (source === "flyby") {
                const [first, last] = argValue(args, "--frames").split("-").map(Number);
                frames.push(...range(first, last));
                assert.equal(command.totalStepCount, last - first + 1);
            } else {
                for (let i = args.indexOf("-s"); i >= 0; i = args.indexOf("-s", i + 1)) {
                    assert.equal(args[i + 2], "-e");
                    assert.equal(args[i + 4], "-a");
                    frames.push(...range(Number(args[i + 1]), Number(args[i + 3])));
                }
                assert.equal(command.totalStepCount, frames.length);
            }
        }
        byTask.push(frames);
    }
    return byTask;
}

function assertChunking(byTask, frames, chunkSize) {
    assert.deepEqual(byTask.flat(), frames, "every frame once, in order");
    for (const chunk of byTask.slice(0, -1)) {
        assert.equal(chunk.length, chunkSize);
    }
    assert.ok(byTask[byTask.length - 1].length <= chunkSize);
}

test("the job type is a proper AvailableJobType named planet-lod", () => {
    assert.equal(loaded.name, "planet-lod");
    assert.deepEqual(flamenco.jobTypeProblems(loaded.jobType), []);
    const keys = loaded.jobType.settings.map((s) => s.key);
    for (const key of ["source", "frames", "chunk_size", "render_output_root", "blendfile", "preset",
                       "quality", "path_frames", "resolution", "samples", "planet_lod_root"]) {
        assert.ok(keys.includes(key), key);
    }
});

test("flyby: one task per chunk, each runs tools/flyby.py over its frames", () => {
    const job = flybyJob({ frames: "1-8", chunk_size: 3, preset: "moon", quality: "draft",
                           path_frames: 8, resolution: "64x36", samples: 1, threads: 2 });
    assert.deepEqual(job.tasks.map((t) => t.name), ["render-1-3", "render-4-6", "render-7,8", "merge-chunks"]);
    const out = `/render/earth/${STAMP}`;
    assert.equal(job.settings.render_output_path, out);
    const first = job.tasks[0];
    assert.equal(first.type, "blender");
    assert.equal(first.commands.length, 1);
    assert.deepEqual(first.commands[0], {
        name: "blender-render",
        parameters: {
            exe: "{blender}", exeArgs: "{blenderArgs}", argsBefore: [], blendfile: "",
            args: ["--python-exit-code", "1", "--python", "{planet_lod}/tools/flyby.py", "--",
                   "--preset", "moon", "--quality", "draft", "--frames", "1-3", "--path-frames", "8",
                   "--resolution", "64x36", "--samples", "1", "--engine", "CYCLES",
                   "--skim-height", "5", "--threads", "2",
                   "--out", `${out}/chunks/frames-0001-0003`],
        },
        totalStepCount: 3,
    });
    assert.equal(argValue(job.tasks[2].commands[0].parameters.args, "--frames"), "7-8");
    assert.equal(argValue(job.tasks[2].commands[0].parameters.args, "--out"), `${out}/chunks/frames-0007-0008`);
    for (const task of job.tasks) {
        for (const command of task.commands) {
            assert.ok(command.parameters.args.every((arg) => typeof arg === "string"), task.name);
        }
    }
});

test("flyby: the merge task runs last, after every render task, over the whole range", () => {
    const job = flybyJob({ frames: "1-10,20-25", chunk_size: 4, planet_lod_root: "/opt/planet-lod" });
    const merge = job.tasks[job.tasks.length - 1];
    assert.equal(merge.name, "merge-chunks");
    const renders = job.tasks.slice(0, -1);
    assert.deepEqual(merge.dependencies.slice().sort(), renders.map((t) => t.uuid).sort());
    for (const task of renders) {
        assert.deepEqual(task.dependencies, []);
    }
    const out = `/render/earth/${STAMP}`;
    assert.deepEqual(merge.commands, [{
        name: "blender-render",
        parameters: {
            exe: "{blender}", exeArgs: "{blenderArgs}", argsBefore: [], blendfile: "",
            args: ["--python-exit-code", "1", "--python", "/opt/planet-lod/farm/flamenco/merge_chunks.py", "--",
                   "--chunks", `${out}/chunks`, "--frames", "1-10,20-25", "--out", out],
        },
        totalStepCount: 0,
    }]);
});

test("flyby: a chunk across a gap in the frames runs one flyby per run of frames", () => {
    const job = flybyJob({ frames: "1-3,7-9", chunk_size: 4 });
    assert.deepEqual(job.tasks.map((t) => t.name), ["render-1-3,7", "render-8,9", "merge-chunks"]);
    const outs = job.tasks[0].commands.map((c) => argValue(c.parameters.args, "--out").split("/").pop());
    assert.deepEqual(outs, ["frames-0001-0003", "frames-0007-0007"]);
    assert.deepEqual(renderedFrames(job, "flyby"), [[1, 2, 3, 7], [8, 9]]);
});

// Fails the task when a planet could not be built from its maps.
const CHECK = "import bpy, importlib; " +
    "bad = importlib.import_module('planet_lod').planet_errors(bpy.context.scene); " +
    "assert not bad, 'planet_lod: ' + '; '.join(bad)";

test("blendfile: -s A -e B -a over each chunk, the add-on enabled before the file loads", () => {
    const job = blendJob({ frames: "1-12", chunk_size: 5 });
    assert.deepEqual(job.tasks.map((t) => t.name),
                     ["render-1-5", "render-6-10", "render-11,12", "merge-stats"]);
    assert.deepEqual(job.tasks[1].commands, [{
        name: "blender-render",
        parameters: {
            exe: "{blender}", exeArgs: "{blenderArgs}", argsBefore: ["--addons", "planet_lod"],
            blendfile: "/jobs/shot.blend",
            args: ["--scene", "Scene", "--python-exit-code", "1", "--python-expr", CHECK,
                   "--render-output", `/render/shot/${STAMP}/frame_######`, "-s", "6", "-e", "10", "-a"],
        },
        totalStepCount: 5,
    }]);
    const line = flamenco.blenderCommandLine(flamenco.expandVariables(job, {
        blender: "/usr/bin/blender", blenderArgs: "-b -y" }).tasks[2].commands[0].parameters);
    assert.deepEqual(line, ["/usr/bin/blender", "-b", "-y", "--addons", "planet_lod", "/jobs/shot.blend",
                            "--scene", "Scene", "--python-exit-code", "1", "--python-expr", CHECK,
                            "--render-output", `/render/shot/${STAMP}/frame_######`,
                            "-s", "11", "-e", "12", "-a"]);
    for (const task of job.tasks.slice(0, 3)) {
        assert.deepEqual(task.dependencies, []);
    }
});

test("blendfile: a last task merges the frames' stats files into stats.csv", () => {
    const job = blendJob({ frames: "1-2,4,9-12", chunk_size: 3,
                           render_output_path: "/render/it's \\ \"here\"/{timestamp}" });
    const merge = job.tasks[job.tasks.length - 1];
    assert.equal(merge.name, "merge-stats");
    assert.deepEqual(merge.dependencies, job.tasks.slice(0, -1).map((t) => t.uuid));
    const parameters = merge.commands[0].parameters;
    assert.equal(parameters.blendfile, "");
    assert.deepEqual(parameters.argsBefore, ["--addons", "planet_lod"]);
    assert.equal(merge.commands[0].totalStepCount, 0);
    // the folder as a Python string literal, quotes and backslashes escaped
    assert.deepEqual(parameters.args, ["--python-exit-code", "1", "--python-expr",
        "import importlib; importlib.import_module('planet_lod').merge_frame_stats(" +
        `"/render/it's \\\\ \\"here\\"/${STAMP}", "1,2,4,9-12")`]);
});

test("blendfile: a chunk across a gap renders each run in the same Blender", () => {
    const job = blendJob({ frames: "1-2,4", chunk_size: 3, scene: "" });
    assert.equal(job.tasks.length, 1 + 1);
    const args = job.tasks[0].commands[0].parameters.args;
    assert.deepEqual(args.slice(6), ["-s", "1", "-e", "2", "-a", "-s", "4", "-e", "4", "-a"]);
    assert.equal(args[0], "--python-exit-code");
    assert.equal(args[4], "--render-output");
});

test("blendfile: an add-on installed as a Blender 4.2+ extension has its own module name", () => {
    const job = blendJob({ frames: "1", addon_module: "bl_ext.user_default.planet_lod" });
    const parameters = job.tasks[0].commands[0].parameters;
    assert.deepEqual(parameters.argsBefore, ["--addons", "bl_ext.user_default.planet_lod"]);
    assert.ok(argValue(parameters.args, "--python-expr").includes(
        "importlib.import_module('bl_ext.user_default.planet_lod')"));
});

test("every frame exactly once, in chunks of the chosen size, for many ranges and sizes", () => {
    let seed = 12345;
    const random = (n) => {
        seed = (seed * 1103515245 + 12345) % 2147483648;
        return seed % n;
    };
    for (let trial = 0; trial < 200; trial++) {
        const parts = [];
        const frames = new Set();
        for (let p = 0; p < 1 + random(4); p++) {
            const first = random(300);
            const last = first + random(40);
            parts.push(random(2) ? `${first}-${last}` : `${first}..${last}`);
            range(first, last).forEach((f) => frames.add(f));
        }
        const spec = parts.join(random(2) ? "," : ", ");
        const chunkSize = 1 + random(25);
        const expected = Array.from(frames).sort((a, b) => a - b);
        const flyby = flybyJob({ frames: spec, chunk_size: chunkSize });
        assertChunking(renderedFrames(flyby, "flyby"), expected, chunkSize);
        assert.equal(flyby.tasks.length, Math.ceil(expected.length / chunkSize) + 1, spec);
        const blend = blendJob({ frames: spec, chunk_size: chunkSize });
        assertChunking(renderedFrames(blend, "blendfile"), expected, chunkSize);
    }
});

test("flyby: a path of waypoints from a file, spread over path_frames when it is a track", () => {
    const job = flybyJob({ frames: "1-20", chunk_size: 10, path_file: "/paths/alps walk.gpx",
                           path_frames: 20 });
    for (const task of job.tasks.slice(0, 2)) {
        const args = task.commands[0].parameters.args;
        assert.equal(argValue(args, "--path"), "/paths/alps walk.gpx");
        assert.equal(argValue(args, "--path-frames"), "20");
    }
    const orbit = flybyJob({ frames: "1-20" });
    assert.ok(!orbit.tasks[0].commands[0].parameters.args.includes("--path"));
    assert.equal(orbit.settings.path_file, "");
});

test("a job sent through the REST API with few settings takes the defaults", () => {
    const job = loaded.compile({ name: "short", type: "planet-lod", created: CREATED,
                                 settings: { source: "flyby", frames: "1-120", render_output_root: "/r" } });
    assert.equal(job.tasks.length, 12 + 1);
    const args = job.tasks[0].commands[0].parameters.args;
    assert.equal(argValue(args, "--preset"), "earth");
    assert.equal(argValue(args, "--quality"), "preview");
    assert.equal(argValue(args, "--path-frames"), "120");
    assert.equal(argValue(args, "--resolution"), "640x360");
    assert.equal(argValue(args, "--samples"), "16");
    assert.equal(argValue(args, "--python"), "{planet_lod}/tools/flyby.py");
    assert.equal(job.settings.chunk_size, 10);
});

test("a job from the Blender submitter: every setting present, evaluated ones included", () => {
    const settings = flamenco.submitterSettings(loaded.jobType,
        { source: "blendfile", chunk_size: 4, render_output_root: "/render" },
        { frames: "1-9", render_output_path: "/render/shot/{timestamp}", format: "OPEN_EXR", scene: "Main" });
    settings.blendfile = "/jobs/shot.flamenco.blend";  // set by the submitter after packing
    const job = loaded.compile({ name: "shot", type: "planet-lod", created: CREATED, settings });
    assert.deepEqual(job.tasks.map((t) => t.name), ["render-1-4", "render-5-8", "render-9", "merge-stats"]);
    const args = job.tasks[0].commands[0].parameters.args;
    assert.equal(argValue(args, "--render-output"), `/render/shot/${STAMP}/frame_######`);
    assert.equal(argValue(args, "--scene"), "Main");
    assert.equal(job.settings.render_output_path, `/render/shot/${STAMP}`);
});

test("bad settings are refused with the setting's name", () => {
    const flybyCases = [
        [{ frames: "" }, /"frames" is required/],
        [{ frames: "1-x" }, /invalid range/],
        [{ frames: "9-3" }, /empty range/],
        [{ frames: "-5--1" }, /invalid range/],
        [{ chunk_size: 0 }, /"chunk_size"/],
        [{ chunk_size: 2.5 }, /"chunk_size"/],
        [{ chunk_size: "4" }, /"chunk_size"/],
        [{ source: "movie" }, /"source" is "movie"; expected one of flyby, blendfile/],
        [{ preset: "pluto" }, /"preset"/],
        [{ quality: "ultra" }, /"quality"/],
        [{ engine: "WORKBENCH" }, /"engine"/],
        [{ resolution: "640" }, /"resolution"/],
        [{ resolution: "0x10" }, /"resolution"/],
        [{ samples: 0 }, /"samples"/],
        [{ path_frames: -1 }, /"path_frames"/],
        [{ path_file: 3 }, /"path_file"/],
        [{ threads: -2 }, /"threads"/],
        [{ skim_height: -1 }, /"skim_height"/],
        [{ skim_height: "high" }, /"skim_height"/],
        [{ render_output_root: "" }, /"render_output_root" is required/],
        [{ planet_lod_root: "" }, /"planet_lod_root"/],
    ];
    for (const [settings, pattern] of flybyCases) {
        assert.throws(() => flybyJob(settings),
                      (e) => e instanceof flamenco.JobCompileError && pattern.test(e.message),
                      JSON.stringify(settings));
    }
    const blendCases = [
        [{ blendfile: "" }, /"blendfile" is required/],
        [{ format: "FFMPEG" }, /movie \(FFMPEG\)/],
        [{ addon_module: "planet_lod'); import os; ('" }, /"addon_module"/],
        [{ addon_module: "" }, /"addon_module"/],
    ];
    for (const [settings, pattern] of blendCases) {
        assert.throws(() => blendJob(settings),
                      (e) => e instanceof flamenco.JobCompileError && pattern.test(e.message),
                      JSON.stringify(settings));
    }
});
