// Compiles a submitted job with a job type script, as the Flamenco Manager
// would, and prints the authored job as JSON (or the error, exit status 1):
//
//     node farm/flamenco/harness/compile.js farm/flamenco/planet_lod.js job.json
//
// job.json is a submitted job: { "name", "type", "priority", "settings",
// "metadata", "created" (optional ISO time) }.  With --job-type it prints the
// job type (what the Manager reports as AvailableJobType) instead.
"use strict";

const fs = require("node:fs");
const flamenco = require("./flamenco.js");

function main(argv) {
    if (argv[0] === "--job-type" && argv.length === 2) {
        const loaded = flamenco.loadJobType(argv[1]);
        return Object.assign({ name: loaded.name }, loaded.jobType);
    }
    if (argv.length !== 2) {
        throw new Error("usage: compile.js JOB_TYPE.js SUBMITTED_JOB.json | --job-type JOB_TYPE.js");
    }
    const loaded = flamenco.loadJobType(argv[0]);
    const submitted = JSON.parse(fs.readFileSync(argv[1], "utf8"));
    return loaded.compile(submitted);
}

try {
    process.stdout.write(JSON.stringify(main(process.argv.slice(2)), null, 1) + "\n");
} catch (error) {
    process.stderr.write(`compile.js: ${error.message}\n`);
    process.exitCode = 1;
}
