// A stand-in for Flamenco's job compiler globals (author, frameChunker, path, print,
// formatTimestampLocal), enough to run a job type's compileJob(job) under node and print the
// tasks it authors as JSON. Usage: node harness.js JOBTYPE.js JOB.json
"use strict";
const fs = require("fs");
const nodePath = require("path").posix;
const vm = require("vm");

// Flamenco's frameChunker: explode "1-3, 7" to frames, cut in chunks, merge each chunk back
// to "a-b" (3+ consecutive frames), "a,b" (two) or "a".
function frameChunker(range, chunkSize) {
    const frames = new Set();
    for (const part of range.split(",").map((p) => p.trim()).filter((p) => p)) {
        const m = /^(\d+)(?:(?:-|\.\.)(\d+))?$/.exec(part);
        if (!m) throw `invalid range "${range}"`;
        const end = m[2] === undefined ? Number(m[1]) : Number(m[2]);
        for (let f = Number(m[1]); f <= end; f++) frames.add(f);
    }
    const list = [...frames].sort((a, b) => a - b);
    const chunks = [];
    for (let i = 0; i < list.length; i += chunkSize) {
        const chunk = list.slice(i, i + chunkSize);
        const ranges = [];
        let start = chunk[0], prev = chunk[0];
        const flush = () => {
            if (start == prev) ranges.push(`${start}`);
            else if (start + 1 == prev) ranges.push(`${start}`, `${prev}`);
            else ranges.push(`${start}-${prev}`);
        };
        for (const f of chunk.slice(1)) {
            if (f > prev + 1) { flush(); start = f; }
            prev = f;
        }
        flush();
        chunks.push(ranges.join(","));
    }
    return chunks;
}

let nextTask = 0;
const author = {
    Task(name, type) {
        return {name, type, commands: [], dependencies: [], id: nextTask++,
                addCommand(c) { this.commands.push(c); },
                addDependency(t) { this.dependencies.push(t.name); }};
    },
    Command(name, parameters) { return {name, parameters}; },
};

const [scriptFile, jobFile] = process.argv.slice(2);
const job = JSON.parse(fs.readFileSync(jobFile, "utf8"));
const tasks = [];
job.created = new Date(job.created);
job.addTask = (t) => tasks.push(t);
const context = {
    author, frameChunker, print: () => {},
    path: {join: nodePath.join, dirname: nodePath.dirname, basename: nodePath.basename},
    formatTimestampLocal: () => "2026-12-01_120000",
};
vm.createContext(context);
vm.runInContext(fs.readFileSync(scriptFile, "utf8") + "\nthis.JOB_TYPE = JOB_TYPE;", context);
context.compileJob(job);
process.stdout.write(JSON.stringify({
    settings: context.JOB_TYPE.settings.map((s) => s.key),
    tasks: tasks.map((t) => ({name: t.name, type: t.type, commands: t.commands,
                              dependencies: t.dependencies})),
}, null, 2) + "\n");
