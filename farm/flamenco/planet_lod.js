// Planet LOD job type for Flamenco 3 (job type name "planet-lod", from this
// file's name).  Copy this file into the `scripts` folder next to the
// flamenco-manager executable and restart the Manager.
//
// Two sources:
//   flyby      Blender builds the scene itself from a planet preset
//              (tools/flyby.py of a Planet LOD checkout on the workers):
//              each task renders one chunk of frames into its own folder with
//              its own stats.csv; a last task merges the chunks into one
//              folder, one stats.csv and one contact sheet.
//   blendfile  the submitted .blend is rendered with `-s A -e B -a`; the
//              planet_lod add-on's frame-change handler refines each planet
//              for that frame's camera before the frame renders.  Through a
//              planet_lod_geo camera each frame writes its own stats file; a
//              last task merges them into one stats.csv.
// The LOD of a frame depends only on that frame's camera, so every chunk size
// gives the same meshes, CSV rows and pictures.
//
// Workers need Blender with the planet_lod add-on installed
// (tools/install_addon.py); flyby jobs also need the checkout, found through
// the `planet_lod_root` setting (by default the Manager variable
// {planet_lod}).

const FLYBY_PRESETS = ["earth", "moon", "mars", "asteroid"];
const FLYBY_QUALITIES = ["draft", "preview", "final"];
const FLYBY_ENGINES = ["CYCLES", "BLENDER_EEVEE"];
// Chunks of a movie file would overwrite each other.
const VIDEO_FORMATS = ["FFMPEG", "AVI_RAW", "AVI_JPEG"];

const JOB_TYPE = {
    label: "Planet LOD",
    description: "Render a Planet LOD flyby from a preset, or a .blend with planets, " +
        "in chunks of frames on workers that have the planet_lod add-on",
    settings: [
        { key: "source", type: "string", choices: ["flyby", "blendfile"], default: "blendfile",
          visible: "submission",
          description: "flyby: build the scene from a planet preset on the worker; " +
              "blendfile: render the submitted .blend" },
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          evalInfo: { showLinkButton: true, description: "Scene frame range" },
          description: "Frames to render, e.g. '1-120' or '1-10, 50-60'" },
        { key: "chunk_size", type: "int32", default: 10, propargs: { min: 1, max: 100000 },
          visible: "submission",
          description: "Frames per task; each task is one Blender process" },

        // Where the frames go: render_output_root/<job name>/<submission time>/
        { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
          visible: "submission",
          description: "Folder under which each job gets <job name>/<submission time>/" },
        { key: "render_output_path", type: "string", subtype: "dir_path", editable: false,
          eval: "str(Path(abspath(settings.render_output_root), jobname, '{timestamp}'))",
          description: "Folder of this job's frames, stats.csv and contact sheet" },

        // source = flyby: the arguments of tools/flyby.py
        { key: "preset", type: "string", choices: FLYBY_PRESETS, default: "earth",
          visible: "submission", description: "Flyby: planet preset" },
        { key: "quality", type: "string", choices: FLYBY_QUALITIES, default: "preview",
          visible: "submission", description: "Flyby: LOD quality preset" },
        { key: "path_frames", type: "int32", default: 120, propargs: { min: 1 },
          visible: "submission",
          description: "Flyby: length of the camera path (orbit, descent, skim) in frames" },
        { key: "path_file", type: "string", subtype: "file_path", default: "", visible: "submission",
          description: "Flyby: waypoints to fly instead of the orbit, descent and skim (.csv, " +
              ".gpx or .kml, as workers see the file; a GPX or KML track is spread over " +
              "path_frames frames); empty for the orbit, descent and skim" },
        { key: "resolution", type: "string", default: "640x360", visible: "submission",
          description: "Flyby: image size, WIDTHxHEIGHT" },
        { key: "samples", type: "int32", default: 16, propargs: { min: 1 },
          visible: "submission", description: "Flyby: Cycles samples per pixel" },
        { key: "engine", type: "string", choices: FLYBY_ENGINES, default: "CYCLES",
          visible: "submission", description: "Flyby: render engine" },
        { key: "skim_height", type: "float", default: 5.0, propargs: { min: 0.0 },
          visible: "submission", description: "Flyby: camera height above the ground at the end, in metres" },
        { key: "threads", type: "int32", default: 0, propargs: { min: 0 },
          visible: "submission", description: "Flyby: render threads per worker (0: all cores)" },
        { key: "planet_lod_root", type: "string", subtype: "dir_path", default: "{planet_lod}",
          visible: "submission",
          description: "Flyby: the Planet LOD checkout as workers see it (tools/flyby.py, " +
              "farm/flamenco/merge_chunks.py); {planet_lod} is a Manager variable" },

        { key: "addon_module", type: "string", default: "planet_lod", visible: "submission",
          description: "Blendfile: the add-on's module on the workers (planet_lod; an extension " +
              "installed in Blender 4.2+ is bl_ext.<repository>.planet_lod)" },

        // source = blendfile: filled in by the Flamenco add-on when it submits.
        { key: "blendfile", type: "string", description: "Path of the .blend to render",
          visible: "web" },
        { key: "format", type: "string", eval: "C.scene.render.image_settings.file_format",
          visible: "web", description: "Image format of the .blend's render output" },
        { key: "scene", type: "string", eval: "C.scene.name", visible: "web",
          description: "Scene of the .blend to render" },
    ],
};

function compileJob(job) {
    const settings = job.settings;
    applyDefaults(settings);
    validateSettings(settings);

    const outputDir = renderOutputDir(job);
    // The job shows the folder it really rendered to.
    settings.render_output_path = outputDir;

    const chunks = frameChunker(settings.frames, settings.chunk_size);
    if (settings.source === "flyby") {
        authorFlybyTasks(job, settings, chunks, outputDir);
    } else {
        authorBlendfileTasks(job, settings, chunks, outputDir);
    }
}

// A job submitted through the REST API may leave settings out: they take the
// defaults the Blender add-on would have shown.
function applyDefaults(settings) {
    for (const setting of JOB_TYPE.settings) {
        const value = settings[setting.key];
        if ((value === undefined || value === null) && setting.default !== undefined) {
            settings[setting.key] = setting.default;
        }
    }
}

function validateSettings(settings) {
    for (const setting of JOB_TYPE.settings) {
        const value = settings[setting.key];
        if (setting.required && (value === undefined || value === null || value === "")) {
            throw `setting "${setting.key}" is required`;
        }
        if (setting.choices && setting.choices.indexOf(value) < 0) {
            throw `setting "${setting.key}" is "${value}"; expected one of ${setting.choices.join(", ")}`;
        }
    }
    requireInteger(settings, "chunk_size", 1);
    if (settings.source === "flyby") {
        requireInteger(settings, "path_frames", 1);
        if (typeof settings.path_file !== "string") {
            throw `setting "path_file" is "${settings.path_file}"; expected a file name or nothing`;
        }
        requireInteger(settings, "samples", 1);
        requireInteger(settings, "threads", 0);
        const skim = Number(settings.skim_height);
        if (typeof settings.skim_height !== "number" || !isFinite(skim) || skim < 0) {
            throw `setting "skim_height" is "${settings.skim_height}"; expected a number >= 0`;
        }
        if (!/^[1-9][0-9]{0,4}x[1-9][0-9]{0,4}$/.test(String(settings.resolution))) {
            throw `setting "resolution" is "${settings.resolution}"; expected WIDTHxHEIGHT, e.g. 640x360`;
        }
        if (!settings.planet_lod_root) {
            throw `setting "planet_lod_root" is required for a flyby`;
        }
    } else {
        if (!/^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$/.test(String(settings.addon_module))) {
            throw `setting "addon_module" is "${settings.addon_module}"; expected a Python module name`;
        }
        if (!settings.blendfile) {
            throw `setting "blendfile" is required to render a .blend`;
        }
        if (VIDEO_FORMATS.indexOf(settings.format) >= 0) {
            throw `the .blend renders to a movie (${settings.format}); chunks need an image format`;
        }
    }
}

function requireInteger(settings, key, minimum) {
    const value = settings[key];
    if (typeof value !== "number" || !isFinite(value) || Math.floor(value) !== value || value < minimum) {
        throw `setting "${key}" is "${value}"; expected a whole number >= ${minimum}`;
    }
}

function renderOutputDir(job) {
    let dir = job.settings.render_output_path;
    if (!dir) {
        dir = path.join(job.settings.render_output_root, job.name, "{timestamp}");
    }
    return dir.replace(/{timestamp}/g, () => formatTimestampLocal(job.created));
}

// "1-3,7" -> [1, 2, 3, 7], with Flamenco's own range rules.
function explodeFrames(frameRange) {
    const frames = [];
    for (const chunk of frameChunker(frameRange, 1)) {
        frames.push(parseInt(chunk, 10));
    }
    return frames;
}

// A chunk from frameChunker ("1-8", "9,10", "4-6,11") as runs of consecutive
// frames: [[1, 8]], [[9, 10]], [[4, 6], [11, 11]].
function consecutiveRuns(chunk) {
    const runs = [];
    for (const frame of explodeFrames(chunk)) {
        const last = runs[runs.length - 1];
        if (last && frame === last[1] + 1) {
            last[1] = frame;
        } else {
            runs.push([frame, frame]);
        }
    }
    return runs;
}

function pad4(frame) {
    const digits = String(frame);
    return digits.length >= 4 ? digits : "0000".slice(digits.length) + digits;
}

function runDirName(run) {
    return `frames-${pad4(run[0])}-${pad4(run[1])}`;
}

// Blender as the Manager configures it.
function blenderCommand(blendfile, argsBefore, args, steps) {
    return author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: argsBefore,
        blendfile: blendfile,
        args: args,
    }, steps);
}

function authorFlybyTasks(job, settings, chunks, outputDir) {
    const root = settings.planet_lod_root;
    const flybyScript = path.join(root, "tools", "flyby.py");
    const mergeScript = path.join(root, "farm", "flamenco", "merge_chunks.py");
    const chunksDir = path.join(outputDir, "chunks");

    const renderTasks = [];
    for (const chunk of chunks) {
        const task = author.Task(`render-${chunk}`, "blender");
        // One Blender per run of consecutive frames: flyby.py takes one range.
        for (const run of consecutiveRuns(chunk)) {
            const args = [
                "--python-exit-code", "1",
                "--python", flybyScript, "--",
                "--preset", settings.preset,
                "--quality", settings.quality,
                "--frames", `${run[0]}-${run[1]}`,
                "--path-frames", String(settings.path_frames),
            ].concat(settings.path_file ? ["--path", settings.path_file] : [], [
                "--resolution", String(settings.resolution),
                "--samples", String(settings.samples),
                "--engine", settings.engine,
                "--skim-height", String(settings.skim_height),
                "--threads", String(settings.threads),
                "--out", path.join(chunksDir, runDirName(run)),
            ]);
            task.addCommand(blenderCommand("", [], args, run[1] - run[0] + 1));
        }
        renderTasks.push(task);
    }

    const merge = author.Task("merge-chunks", "blender");
    merge.addCommand(blenderCommand("", [], [
        "--python-exit-code", "1",
        "--python", mergeScript, "--",
        "--chunks", chunksDir,
        "--frames", frameChunker(settings.frames, Number.MAX_SAFE_INTEGER)[0],
        "--out", outputDir,
    ], 0));
    // Dependencies go in before the task is added: the job keeps a copy.
    for (const task of renderTasks) {
        merge.addDependency(task);
        job.addTask(task);
    }
    job.addTask(merge);
}

// Python run after the .blend loaded: fails the task when a planet could not
// be built (a height map the .blend names is not on this worker, the add-on
// is missing), instead of rendering the mesh saved in the file.
function planetCheck(module) {
    return [
        "import bpy, importlib",
        `bad = importlib.import_module('${module}').planet_errors(bpy.context.scene)`,
        "assert not bad, 'planet_lod: ' + '; '.join(bad)",
    ].join("; ");
}

function authorBlendfileTasks(job, settings, chunks, outputDir) {
    // Enabled before the .blend loads, so that the add-on's load handler
    // builds the planets from their maps.
    const before = ["--addons", settings.addon_module];
    const check = ["--python-exit-code", "1", "--python-expr", planetCheck(settings.addon_module)];
    const sceneArgs = settings.scene ? ["--scene", settings.scene] : [];
    const renderTasks = [];
    for (const chunk of chunks) {
        const task = author.Task(`render-${chunk}`, "blender");
        const args = sceneArgs.concat(check, ["--render-output", path.join(outputDir, "frame_######")]);
        // Blender runs its arguments in order: one process renders every run.
        let steps = 0;
        for (const run of consecutiveRuns(chunk)) {
            args.push("-s", String(run[0]), "-e", String(run[1]), "-a");
            steps += run[1] - run[0] + 1;
        }
        task.addCommand(blenderCommand(settings.blendfile, before, args, steps));
        renderTasks.push(task);
    }

    // Frames rendered through a planet_lod_geo camera leave one stats file
    // each (chunks render at the same time); this task writes stats.csv from
    // them, and does nothing for a .blend whose camera is not one.
    const stats = author.Task("merge-stats", "blender");
    const allFrames = frameChunker(settings.frames, Number.MAX_SAFE_INTEGER)[0];
    stats.addCommand(blenderCommand("", before, ["--python-exit-code", "1", "--python-expr",
        mergeStats(settings.addon_module, outputDir, allFrames)], 0));
    for (const task of renderTasks) {
        stats.addDependency(task);
        job.addTask(task);
    }
    job.addTask(stats);
}

// Python that writes OUT/stats.csv from the frames' own stats files; JSON's
// string literals are Python's too.
function mergeStats(module, outputDir, frames) {
    return `import importlib; importlib.import_module('${module}').merge_frame_stats(` +
        `${JSON.stringify(outputDir)}, ${JSON.stringify(frames)})`;
}
