// The stand-in Manager behaves as Flamenco's job compiler documents: frame
// ranges, paths, tasks and commands, copies at the script boundary.
"use strict";

const assert = require("node:assert/strict");
const fs = require("node:fs");
const os = require("node:os");
const nodePath = require("node:path");
const test = require("node:test");

const flamenco = require("../harness/flamenco.js");

test("frameChunker: chunks of at most N frames; runs of three or more as A-B", () => {
    assert.deepEqual(flamenco.frameChunker("1-10", 4), ["1-4", "5-8", "9,10"]);
    assert.deepEqual(flamenco.frameChunker("1..10", 10), ["1-10"]);
    assert.deepEqual(flamenco.frameChunker("1-3", 1), ["1", "2", "3"]);
    assert.deepEqual(flamenco.frameChunker("1,3,5", 2), ["1,3", "5"]);
    assert.deepEqual(flamenco.frameChunker(" 1..10,20..25,40 ", 4),
                     ["1-4", "5-8", "9,10,20,21", "22-25", "40"]);
    // duplicates and order do not matter
    assert.deepEqual(flamenco.frameChunker("5-7, 1-5, 6", 100), ["1-7"]);
    assert.deepEqual(flamenco.frameChunker("47", 3), ["47"]);
    assert.deepEqual(flamenco.frameChunker(47, "2"), ["47"]);
});

test("frameChunker refuses empty or malformed ranges and chunk sizes below 1", () => {
    for (const bad of ["", "  ", "abc", "1-x", "1-2-3", "5-1", "1,,2", "-3", "1.5"]) {
        assert.throws(() => flamenco.frameChunker(bad, 2), /invalid range/, bad);
    }
    for (const size of [0, -1, undefined, "x"]) {
        assert.throws(() => flamenco.frameChunker("1-10", size), /invalid chunk size/, String(size));
    }
    assert.deepEqual(flamenco.frameChunker("1-5", 2.9), ["1,2", "3,4", "5"]);
});

test("frameCount counts distinct frames", () => {
    assert.equal(flamenco.frameCount("1-10"), 10);
    assert.equal(flamenco.frameCount("9,10,20,21"), 4);
    assert.equal(flamenco.frameCount("3-6,4"), 4);
    assert.throws(() => flamenco.frameCount("a"), /invalid range/);
});

test("path: forward slashes; Windows backslashes read as separators", () => {
    const p = flamenco.path;
    assert.equal(p.join("/render", "job", "frame_####"), "/render/job/frame_####");
    assert.equal(p.join("{planet_lod}", "tools", "flyby.py"), "{planet_lod}/tools/flyby.py");
    // cleaned before the backslashes turn into slashes, as the Manager does
    assert.equal(p.join("C:\\render\\", "a/./b/../c"), "C:/render//a/c");
    assert.equal(p.join("/render//x/", "./y"), "/render/x/y");
    assert.equal(p.join("", ""), "");
    assert.equal(p.dirname("/render/job/frame_####"), "/render/job");
    assert.equal(p.dirname("//NAS/share/x"), "//NAS/share");
    assert.equal(p.dirname("file.blend"), ".");
    assert.equal(p.basename("C:\\scenes\\earth.flamenco.blend"), "earth.flamenco.blend");
    assert.equal(p.basename("/render/job/"), "job");
    assert.equal(p.stem("/a/earth.blend"), "earth");
});

test("formatTimestampLocal gives a file-name-safe local time", () => {
    assert.equal(flamenco.formatTimestampLocal(new Date(2001, 1, 3, 4, 5, 6)), "2001-02-03_040506");
});

test("shellSplit splits like a shell", () => {
    assert.deepEqual(flamenco.shellSplit("-b -y"), ["-b", "-y"]);
    assert.deepEqual(flamenco.shellSplit(`--python-expr "import bpy" 'a b' c\\ d`),
                     ["--python-expr", "import bpy", "a b", "c d"]);
    assert.throws(() => flamenco.shellSplit('"open'), /closing quote/);
});

function scriptFile(t, name, source) {
    const dir = fs.mkdtempSync(nodePath.join(os.tmpdir(), "flamenco-harness-"));
    t.after(() => fs.rmSync(dir, { recursive: true, force: true }));
    const file = nodePath.join(dir, name);
    fs.writeFileSync(file, source);
    return file;
}

const MINIMAL = `
const JOB_TYPE = { label: "Minimal", settings: [
    { key: "message", type: "string", default: "hi" },
] };
`;

test("a script runs in strict mode; the job type name comes from the file name", (t) => {
    const file = scriptFile(t, "two_words.js", MINIMAL + `
function compileJob(job) {
    undeclared = 1;  // a ReferenceError in strict mode
}`);
    const loaded = flamenco.loadJobType(file);
    assert.equal(loaded.name, "two-words");
    assert.throws(() => loaded.compile({ name: "x", settings: {} }), /undeclared is not defined/);
});

test("tasks and commands are copied when they cross into the Manager", (t) => {
    const file = scriptFile(t, "copies.js", MINIMAL + `
function compileJob(job) {
    const args = ["a"];
    const first = author.Task("first", "misc");
    first.addCommand(author.Command("exec", { exe: "echo", args: args }, 2));
    args.push("changed after author.Command");
    job.addTask(first);
    const second = author.Task("  second ", "misc");
    second.addCommand(author.Command("exec", { exe: "echo", args: [] }));
    job.addTask(second);
    second.addDependency(first);  // too late: the job holds a copy already
    job.settings.message = job.settings.message + "!";
    if (typeof first.uUID !== "string" || first.uuid !== undefined || typeof job.jobID !== "string") {
        throw "field names are not the Manager's";
    }
}`);
    const job = flamenco.loadJobType(file).compile({ name: "j", settings: { message: "hello" } });
    assert.deepEqual(job.tasks.map((task) => task.name), ["first", "second"]);
    assert.deepEqual(job.tasks[0].commands[0], { name: "exec", parameters: { exe: "echo", args: ["a"] },
                                                 totalStepCount: 2 });
    assert.equal(job.tasks[1].commands[0].totalStepCount, 0);
    assert.deepEqual(job.tasks[1].dependencies, []);
    assert.equal(job.tasks[0].priority, 50);
    assert.equal(job.settings.message, "hello!");
});

test("compilation fails on a thrown string, a bad built-in call, or a job the Manager refuses", (t) => {
    const cases = [
        ["throw 'no good';", /no good/],
        ["author.Task('', 'blender');", /name is required/],
        ["author.Task('x', ' ');", /type is required/],
        ["frameChunker('1-x', 1);", /invalid range/],
        ["const a = author.Task('a', 'misc'); const b = author.Task('b', 'misc');" +
            "a.addCommand(author.Command('exec', {exe: 'x'})); a.addDependency(b); job.addTask(a);",
         /not part of this job/],
        ["const a = author.Task('a', 'gpu'); a.addCommand(author.Command('exec', {exe: 'x'})); job.addTask(a);",
         /no default worker runs/],
        ["job.addTask(author.Task('a', 'misc'));", /has no commands/],
        ["const a = author.Task('a', 'blender');" +
            "a.addCommand(author.Command('blender-render', {exe: '{blender}', args: []})); job.addTask(a);",
         /string "blendfile"/],
    ];
    for (const [body, pattern] of cases) {
        const file = scriptFile(t, "failing.js", MINIMAL + `function compileJob(job) { ${body} }`);
        assert.throws(() => flamenco.loadJobType(file).compile({ name: "j", settings: {} }),
                      (error) => error instanceof flamenco.JobCompileError && pattern.test(error.message),
                      body);
    }
});

test("a JOB_TYPE outside the AvailableJobType schema is refused at load", (t) => {
    const bad = [
        [`{ settings: [] }`, /label/],
        [`{ label: "x", settings: [{ key: "a", type: "int" }] }`, /type must be one of/],
        [`{ label: "x", settings: [{ key: "a", type: "int32", choices: ["1"] }] }`, /only work with type string/],
        [`{ label: "x", settings: [{ key: "a", type: "int32", default: 1.5 }] }`, /is not a int32/],
        [`{ label: "x", settings: [{ key: "a", type: "string", choices: ["b"], default: "c" }] }`, /not one of its choices/],
        [`{ label: "x", settings: [{ key: "a", type: "string" }, { key: "a", type: "bool" }] }`, /not unique/],
        [`{ label: "x", settings: [{ key: "a", type: "string", visible: "always" }] }`, /visible must be/],
        [`{ label: "x", settings: [{ key: "a", type: "string", eval: "1", evalInfo: {} }] }`, /evalInfo/],
    ];
    for (const [jobType, pattern] of bad) {
        const file = scriptFile(t, "schema.js", `const JOB_TYPE = ${jobType}; function compileJob(job) {}`);
        assert.throws(() => flamenco.loadJobType(file), pattern, jobType);
    }
    const noCompile = scriptFile(t, "nocompile.js", MINIMAL);
    assert.throws(() => flamenco.loadJobType(noCompile), /does not define a compileJob/);
});

test("a worker's blender-render command line: exe, exeArgs, argsBefore, blend file, args", () => {
    const parameters = { exe: "/opt/blender/blender", exeArgs: "-b -y", argsBefore: ["--addons", "x"],
                         blendfile: "/jobs/a.blend", args: ["-a"] };
    assert.deepEqual(flamenco.blenderCommandLine(parameters),
                     ["/opt/blender/blender", "-b", "-y", "--addons", "x", "/jobs/a.blend", "-a"]);
    assert.deepEqual(flamenco.blenderCommandLine(Object.assign({}, parameters, { blendfile: "" })),
                     ["/opt/blender/blender", "-b", "-y", "--addons", "x", "-a"]);
});
