// A stand-in for the job compiler of the Flamenco 3 Manager, to test job type
// scripts with plain node (no packages).  It is written from the behaviour
// that Flamenco's Manager documents and implements (its Go job-compiler
// package, the OpenAPI schema of job types, the worker's command parameters):
//
// * a script runs in strict mode with the globals print, alert, frameChunker,
//   frameCount, formatTimestampLocal, shellSplit and the modules author, path,
//   process; its file name gives the job type name ("planet_lod.js" ->
//   "planet-lod");
// * JOB_TYPE must fit the AvailableJobType schema (settings with key, type
//   string|int32|float|bool, optional subtype, choices, propargs, default,
//   eval, evalInfo, visible, required, editable);
// * compileJob(job) gets an authored job { jobID, name, jobType, priority,
//   status, created, settings, metadata, storage, workerTagUUID, tasks,
//   addTask() }; author.Task(name, type) makes a task { uUID, name, type,
//   priority, commands, dependencies, addCommand(), addDependency() } and
//   author.Command(name, parameters, totalStepCount) a command; field names
//   are the Manager's Go names with the first letter lower-cased (UUID ->
//   uUID).  Values cross into the Manager as copies:
//   a command's parameters when author.Command() is called, a task when
//   job.addTask() is called (its later changes are lost);
// * an error of a built-in (a bad frame range, an unnamed task) and anything
//   the script throws fails the compilation;
// * the Manager stores a task's dependencies only if they are tasks of the
//   same job, and a worker accepts a "blender-render" command only with a
//   non-empty `exe`, a string `blendfile` and list `argsBefore` / `args`.
"use strict";

const crypto = require("node:crypto");
const fs = require("node:fs");
const nodePath = require("node:path");
const vm = require("node:vm");

class JobCompileError extends Error {}

// ---- frame ranges: "1-10,20..25,40" ------------------------------------------

function goInt(value) {
    // How the Manager's JavaScript engine turns a JS value into a Go int.
    const number = Number(value);
    return Number.isNaN(number) ? 0 : Math.trunc(number);
}

function parseFrameNumber(text, range) {
    const trimmed = text.trim();
    if (!/^[+-]?[0-9]+$/.test(trimmed)) {
        throw new Error(`invalid range "${range}": ${text} (cannot parse "${trimmed}" as a whole number)`);
    }
    return parseInt(trimmed, 10);
}

// Every frame of the range, once each, ascending.
function explodeFrameRange(frameRange) {
    const normalised = String(frameRange).split("..").join("-");
    const frames = new Set();
    for (const part of normalised.split(",")) {
        const ends = part.split("-");
        if (ends.length === 1) {
            frames.add(parseFrameNumber(ends[0], normalised));
        } else if (ends.length === 2) {
            const first = parseFrameNumber(ends[0], normalised);
            const last = parseFrameNumber(ends[1], normalised);
            for (let frame = first; frame <= last; frame++) {
                frames.add(frame);
            }
        } else {
            throw new Error(`invalid range "${normalised}": ${part}`);
        }
    }
    return Array.from(frames).sort((a, b) => a - b);
}

// [3,4,5,6,9,11,12] -> "3-6,9,11,12": runs of three or more frames become
// "A-B", shorter runs are listed.
function mergeFrames(frames) {
    const parts = [];
    let start = 0;
    for (let i = 1; i <= frames.length; i++) {
        if (i < frames.length && frames[i] === frames[i - 1] + 1) {
            continue;
        }
        const first = frames[start];
        const last = frames[i - 1];
        if (last - first >= 2) {
            parts.push(`${first}-${last}`);
        } else {
            for (let frame = first; frame <= last; frame++) {
                parts.push(String(frame));
            }
        }
        start = i;
    }
    return parts.join(",");
}

function frameChunker(frameRange, chunkSize) {
    const range = String(frameRange).trim();
    if (range.length === 0) {
        throw new Error(`invalid range "${range}": empty range`);
    }
    const size = goInt(chunkSize);
    if (size < 1) {
        throw new Error(`invalid chunk size, must be positive number: ${size}`);
    }
    const frames = explodeFrameRange(range);
    if (frames.length === 0) {
        throw new Error(`invalid range "${range}": empty range`);
    }
    const chunks = [];
    for (let i = 0; i < frames.length; i += size) {
        chunks.push(mergeFrames(frames.slice(i, i + size)));
    }
    return chunks;
}

function frameCount(frameRange) {
    return explodeFrameRange(frameRange).length;
}

// ---- other globals -------------------------------------------------------------

function pad(number, width) {
    return String(number).padStart(width, "0");
}

// Local time as "2006-01-02_150405" (safe in file names).
function formatTimestampLocal(date) {
    const d = date instanceof Date ? date : new Date(date);
    return `${d.getFullYear()}-${pad(d.getMonth() + 1, 2)}-${pad(d.getDate(), 2)}_` +
        `${pad(d.getHours(), 2)}${pad(d.getMinutes(), 2)}${pad(d.getSeconds(), 2)}`;
}

// Shell-like word splitting: blanks separate words, quotes group them,
// a backslash escapes the next character (not inside single quotes).
function shellSplit(text) {
    const words = [];
    let word = null;
    let quote = null;
    for (let i = 0; i < text.length; i++) {
        const c = text[i];
        if (quote === "'") {
            if (c === "'") { quote = null; } else { word += c; }
        } else if (c === "\\") {
            if (i + 1 >= text.length) { throw new Error("EOF found after escape character"); }
            word = (word || "") + text[++i];
        } else if (quote === '"') {
            if (c === '"') { quote = null; } else { word += c; }
        } else if (c === "'" || c === '"') {
            quote = c;
            word = word || "";
        } else if (/\s/.test(c)) {
            if (word !== null) { words.push(word); word = null; }
        } else {
            word = (word || "") + c;
        }
    }
    if (quote) { throw new Error("EOF found when expecting closing quote"); }
    if (word !== null) { words.push(word); }
    return words;
}

// ---- the path module: forward slashes, Windows backslashes read as slashes ----

function toSlash(p) {
    return String(p).split("\\").join("/");
}

// Lexical clean-up: one slash between names, no "." names, ".." resolved
// where it can be; "" becomes ".".
function cleanPath(p) {
    if (p === "") {
        return ".";
    }
    const rooted = p.startsWith("/");
    const names = [];
    for (const name of p.split("/")) {
        if (name === "" || name === ".") {
            continue;
        }
        if (name === "..") {
            if (names.length > 0 && names[names.length - 1] !== "..") {
                names.pop();
            } else if (!rooted) {
                names.push("..");
            }
            continue;
        }
        names.push(name);
    }
    const joined = names.join("/");
    if (rooted) {
        return "/" + joined;
    }
    return joined === "" ? "." : joined;
}

const pathModule = {
    basename(p) {
        let s = toSlash(p);
        if (s === "") {
            return ".";
        }
        s = s.replace(/\/+$/, "");
        if (s === "") {
            return "/";
        }
        return s.slice(s.lastIndexOf("/") + 1);
    },
    dirname(p) {
        if (p === "") {
            return ".";
        }
        const s = toSlash(p);
        const dir = s.slice(0, s.lastIndexOf("/") + 1);
        if (dir === "") {
            return ".";
        }
        return dir.length > 1 ? dir.slice(0, -1) : dir;
    },
    join(...names) {
        const kept = names.map(String).filter((name) => name !== "");
        return kept.length === 0 ? "" : toSlash(cleanPath(kept.join("/")));
    },
    stem(p) {
        const base = pathModule.basename(p);
        const dot = base.lastIndexOf(".");
        return dot < 0 ? base : base.slice(0, dot);
    },
};

// ---- author: tasks and commands ------------------------------------------------

function snapshot(value) {
    // What crosses from the script into the Manager: plain data, copied.
    return value === undefined ? null : JSON.parse(JSON.stringify(value));
}

// Field names as a script sees them: the Manager's engine lower-cases the
// first letter of its Go field names (UUID -> uUID, JobID -> jobID).
class AuthoredTask {
    constructor(name, type) {
        this.uUID = crypto.randomUUID();
        this.name = name;
        this.type = type;
        this.priority = 50;
        this.commands = [];
        this.dependencies = [];
    }

    addCommand(command) {
        if (!(command instanceof AuthoredCommand)) {
            throw new Error("task.addCommand() takes a command made by author.Command()");
        }
        this.commands.push(command);
    }

    addDependency(task) {
        if (!(task instanceof AuthoredTask)) {
            throw new Error("task.addDependency() takes a task made by author.Task()");
        }
        this.dependencies.push(task);
    }
}

class AuthoredCommand {
    constructor(name, parameters, totalStepCount) {
        this.name = name;
        this.parameters = parameters;
        this.totalStepCount = totalStepCount;
    }
}

const author = {
    Task(name, type) {
        const taskName = String(name === undefined ? "" : name).trim();
        const taskType = String(type === undefined ? "" : type).trim();
        if (taskName === "") {
            throw new Error("author.Task(name, type): name is required");
        }
        if (taskType === "") {
            throw new Error("author.Task(name, type): type is required");
        }
        return new AuthoredTask(taskName, taskType);
    },
    Command(name, parameters, totalStepCount) {
        return new AuthoredCommand(String(name), snapshot(parameters || {}), goInt(totalStepCount));
    },
};

// ---- loading a job type script -------------------------------------------------

const SETTING_TYPES = ["string", "int32", "float", "bool"];
const SETTING_SUBTYPES = ["file_path", "dir_path", "file_name", "hashed_file_path"];
const SETTING_VISIBILITY = ["visible", "hidden", "submission", "web"];

function fitsType(type, value) {
    switch (type) {
    case "string": return typeof value === "string";
    case "int32": return Number.isInteger(value) && value >= -(2 ** 31) && value < 2 ** 31;
    case "float": return typeof value === "number" && Number.isFinite(value);
    case "bool": return typeof value === "boolean";
    default: return false;
    }
}

// Checks JOB_TYPE against the AvailableJobType schema; returns problems.
function jobTypeProblems(jobType) {
    const problems = [];
    if (typeof jobType !== "object" || jobType === null) {
        return ["JOB_TYPE is not an object"];
    }
    if (typeof jobType.label !== "string" || jobType.label === "") {
        problems.push("JOB_TYPE.label must be a non-empty string");
    }
    if (!Array.isArray(jobType.settings)) {
        return problems.concat(["JOB_TYPE.settings must be an array"]);
    }
    const keys = new Set();
    for (const setting of jobType.settings) {
        const where = `setting ${JSON.stringify(setting && setting.key)}`;
        if (typeof setting.key !== "string" || setting.key === "") {
            problems.push(`${where}: key must be a non-empty string`);
        } else if (keys.has(setting.key)) {
            problems.push(`${where}: key is not unique`);
        }
        keys.add(setting.key);
        if (SETTING_TYPES.indexOf(setting.type) < 0) {
            problems.push(`${where}: type must be one of ${SETTING_TYPES.join(", ")}`);
        }
        if (setting.subtype !== undefined && SETTING_SUBTYPES.indexOf(setting.subtype) < 0) {
            problems.push(`${where}: subtype must be one of ${SETTING_SUBTYPES.join(", ")}`);
        }
        if (setting.visible !== undefined && SETTING_VISIBILITY.indexOf(setting.visible) < 0) {
            problems.push(`${where}: visible must be one of ${SETTING_VISIBILITY.join(", ")}`);
        }
        for (const flag of ["required", "editable"]) {
            if (setting[flag] !== undefined && typeof setting[flag] !== "boolean") {
                problems.push(`${where}: ${flag} must be true or false`);
            }
        }
        if (setting.eval !== undefined && typeof setting.eval !== "string") {
            problems.push(`${where}: eval must be a Python expression in a string`);
        }
        if (setting.evalInfo !== undefined && (typeof setting.evalInfo.showLinkButton !== "boolean" ||
                                               typeof setting.evalInfo.description !== "string")) {
            problems.push(`${where}: evalInfo needs showLinkButton (bool) and description (string)`);
        }
        if (setting.propargs !== undefined && (typeof setting.propargs !== "object" || setting.propargs === null)) {
            problems.push(`${where}: propargs must be an object`);
        }
        if (setting.choices !== undefined) {
            if (setting.type !== "string") {
                problems.push(`${where}: choices only work with type string`);
            } else if (!Array.isArray(setting.choices) || setting.choices.length === 0 ||
                       !setting.choices.every((choice) => typeof choice === "string")) {
                problems.push(`${where}: choices must be a non-empty list of strings`);
            }
        }
        if (setting.default !== undefined) {
            if (!fitsType(setting.type, setting.default)) {
                problems.push(`${where}: default ${JSON.stringify(setting.default)} is not a ${setting.type}`);
            } else if (Array.isArray(setting.choices) && setting.choices.indexOf(setting.default) < 0) {
                problems.push(`${where}: default is not one of its choices`);
            }
        }
    }
    return problems;
}

function jobTypeNameOf(file) {
    const base = nodePath.basename(file);
    return base.slice(0, base.length - nodePath.extname(base).length).split("_").join("-");
}

// Loads a job type script as the Manager does; returns { name, jobType,
// compile(submittedJob) }.
function loadJobType(file, options = {}) {
    const source = fs.readFileSync(file, "utf8");
    const printed = options.printed || [];
    const context = vm.createContext({
        print: (...args) => printed.push(args.map(String).join(" ")),
        alert: (...args) => printed.push("alert: " + args.map(String).join(" ")),
        frameChunker,
        frameCount,
        formatTimestampLocal,
        shellSplit,
        author,
        path: pathModule,
        process: { cwd: () => process.cwd(), platform: options.platform || "linux" },
    });
    // Strict mode, as the Manager compiles scripts (first line kept in place).
    new vm.Script('"use strict"; ' + source, { filename: file }).runInContext(context);
    const jobType = vm.runInContext("typeof JOB_TYPE === 'undefined' ? undefined : JOB_TYPE", context);
    const compileJob = vm.runInContext("typeof compileJob === 'function' ? compileJob : undefined", context);
    if (jobType === undefined) {
        throw new JobCompileError(`script (${file}) does not define a JOB_TYPE object`);
    }
    if (compileJob === undefined) {
        throw new JobCompileError(`script (${file}) does not define a compileJob(job) function`);
    }
    const problems = jobTypeProblems(jobType);
    if (problems.length > 0) {
        throw new JobCompileError(`script (${file}) does not define a proper JOB_TYPE object: ` +
                                  problems.join("; "));
    }
    const name = jobTypeNameOf(file);
    return {
        name,
        jobType: snapshot(jobType),
        printed,
        compile(submitted) {
            return compile(name, compileJob, submitted);
        },
    };
}

// ---- compiling a submitted job -------------------------------------------------

const WORKER_TASK_TYPES = ["blender", "ffmpeg", "file-management", "misc"];

function compile(jobTypeName, compileJob, submitted) {
    const tasks = [];
    const job = {
        jobID: crypto.randomUUID(),
        workerTagUUID: submitted.worker_tag || "",
        name: submitted.name,
        jobType: jobTypeName,
        priority: submitted.priority === undefined ? 50 : submitted.priority,
        status: "under-construction",
        created: submitted.created ? new Date(submitted.created) : new Date(),
        settings: Object.assign({}, submitted.settings || {}),
        metadata: Object.assign({}, submitted.metadata || {}),
        storage: { shamanCheckoutID: (submitted.storage && submitted.storage.shaman_checkout_id) || "" },
        tasks,
        addTask(task) {
            if (!(task instanceof AuthoredTask)) {
                throw new Error("job.addTask() takes a task made by author.Task()");
            }
            tasks.push({
                uuid: task.uUID,
                name: task.name,
                type: task.type,
                priority: task.priority,
                commands: task.commands.map((c) => ({
                    name: c.name, parameters: c.parameters, totalStepCount: c.totalStepCount,
                })),
                dependencies: task.dependencies.map((dep) => dep.uUID),
            });
        },
    };
    if (submitted.type !== undefined && submitted.type !== jobTypeName) {
        throw new JobCompileError(`job type unknown: "${submitted.type}"`);
    }
    try {
        compileJob(job);
    } catch (error) {
        // The script's own Error objects come from its own realm.
        const message = error !== null && typeof error === "object" && typeof error.message === "string"
            ? error.message : String(error);
        throw new JobCompileError(message);
    }
    const authored = {
        jobID: job.jobID,
        name: job.name,
        jobType: job.jobType,
        priority: job.priority,
        settings: snapshot(job.settings),
        metadata: snapshot(job.metadata),
        tasks: snapshot(tasks),
    };
    const problems = authoredJobProblems(authored);
    if (problems.length > 0) {
        throw new JobCompileError("the Manager would refuse this job: " + problems.join("; "));
    }
    return authored;
}

// What the Manager's storage and its workers would refuse.
function authoredJobProblems(job) {
    const problems = [];
    const uuids = new Set(job.tasks.map((task) => task.uuid));
    if (uuids.size !== job.tasks.length) {
        problems.push("a task was added twice");
    }
    for (const task of job.tasks) {
        for (const dep of task.dependencies) {
            if (!uuids.has(dep)) {
                problems.push(`task "${task.name}" depends on a task that is not part of this job`);
            }
        }
        if (WORKER_TASK_TYPES.indexOf(task.type) < 0) {
            problems.push(`task "${task.name}" has type "${task.type}", which no default worker runs`);
        }
        if (task.commands.length === 0) {
            problems.push(`task "${task.name}" has no commands`);
        }
        for (const command of task.commands) {
            const p = command.parameters;
            if (command.name !== "blender-render") {
                continue;
            }
            if (typeof p.exe !== "string" || p.exe === "") {
                problems.push(`task "${task.name}": blender-render needs a non-empty "exe"`);
            }
            if (p.exeArgs !== undefined && typeof p.exeArgs !== "string") {
                problems.push(`task "${task.name}": blender-render "exeArgs" must be a string`);
            }
            if (typeof p.blendfile !== "string") {
                problems.push(`task "${task.name}": blender-render needs a string "blendfile"`);
            }
            for (const key of ["argsBefore", "args"]) {
                if (p[key] !== undefined && !Array.isArray(p[key])) {
                    problems.push(`task "${task.name}": blender-render "${key}" must be a list`);
                }
            }
        }
    }
    return problems;
}

// ---- what a submitter does before it sends a job ---------------------------------

// The settings a Blender submitter sends: every setting of the job type, the
// artist's value where given, else for settings it evaluates (hidden and web
// ones, or an `eval` it was told to follow) the value of its `eval`
// expression, taken from `evaluated` (the harness runs no Python), else the
// default.
function submitterSettings(jobType, chosen = {}, evaluated = {}) {
    const settings = {};
    for (const setting of jobType.settings) {
        const shown = setting.visible === undefined || setting.visible === "visible" ||
            setting.visible === "submission";
        if (shown && Object.prototype.hasOwnProperty.call(chosen, setting.key)) {
            settings[setting.key] = chosen[setting.key];
        } else if (setting.eval) {
            if (!Object.prototype.hasOwnProperty.call(evaluated, setting.key)) {
                throw new Error(`no value given for the eval of setting "${setting.key}": ${setting.eval}`);
            }
            settings[setting.key] = evaluated[setting.key];
        } else if (setting.default !== undefined) {
            settings[setting.key] = setting.default;
        } else if (Object.prototype.hasOwnProperty.call(chosen, setting.key)) {
            settings[setting.key] = chosen[setting.key];
        }
    }
    return settings;
}

// Manager variables ({blender}, {blenderArgs}, ...) as a worker receives them.
function expandVariables(job, variables) {
    const expand = (text) => text.replace(/{([^}]+)}/g, (match, name) =>
        Object.prototype.hasOwnProperty.call(variables, name) ? variables[name] : match);
    const copy = snapshot(job);
    for (const task of copy.tasks) {
        for (const command of task.commands) {
            for (const [key, value] of Object.entries(command.parameters)) {
                if (typeof value === "string") {
                    command.parameters[key] = expand(value);
                } else if (Array.isArray(value)) {
                    command.parameters[key] = value.map((item) => typeof item === "string" ? expand(item) : item);
                }
            }
        }
    }
    return copy;
}

// The command line a worker runs for a "blender-render" command: exe, then
// exeArgs split like a shell, argsBefore, the blend file if any, args.
function blenderCommandLine(parameters) {
    const line = [parameters.exe].concat(shellSplit(parameters.exeArgs || ""), parameters.argsBefore || []);
    if (parameters.blendfile) {
        line.push(parameters.blendfile);
    }
    return line.concat(parameters.args || []);
}

module.exports = {
    JobCompileError,
    blenderCommandLine,
    expandVariables,
    formatTimestampLocal,
    frameChunker,
    frameCount,
    jobTypeProblems,
    loadJobType,
    path: pathModule,
    shellSplit,
    submitterSettings,
};
