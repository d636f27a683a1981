// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco v3 job type "VPL GI Render": frames in chunks, rendered with the VPL_GI engine and
// its settings pinned on the command line, so that a frame does not depend on the worker or
// on the chunk it was rendered in. Copy this file into the `scripts/` folder next to the
// Flamenco Manager binary. Workers run `{blender}`: Blender with the VPL GI extension, or
// tools/vplgi-blender (the bpy module) from this repository.

const JOB_TYPE = {
    label: "VPL GI Render",
    settings: [
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          description: "Frame range to render. Examples: '47', '1-30', '3, 5-10, 47-327'" },
        { key: "chunk_size", type: "int32", default: 1, visible: "submission",
          description: "Number of frames to render in one task" },

        { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
          visible: "submission",
          description: "Base directory of the render output; job-specific parts are appended" },
        { key: "add_path_components", type: "int32", required: true, default: 0,
          propargs: {min: 0, max: 32}, visible: "submission",
          description: "Number of path components of the blend file used in the output path" },
        { key: "render_output_path", type: "string", subtype: "file_path", editable: false,
          eval: "str(Path(bpy.path.abspath(settings.render_output_root), last_n_dir_parts(settings.add_path_components), jobname, '{timestamp}', '######'))",
          description: "Final file path of the render output" },

        { key: "blender_cmd", type: "string", default: "{blender}", visible: "hidden" },
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Path of the blend file to render" },
        { key: "scene", type: "string", required: true, eval: "C.scene.name", visible: "web",
          description: "Scene to render" },
        { key: "format", type: "string", required: true, default: "PNG",
          choices: ["PNG", "OPEN_EXR"], visible: "submission",
          description: "PNG (view transform applied) or OPEN_EXR (linear)" },

        // VPL GI settings pinned on every task (scene.vpl_gi.<name>).
        { key: "passes", type: "int32", default: 1, propargs: {min: 1, max: 65536},
          eval: "C.scene.vpl_gi.passes", visible: "submission",
          description: "Passes per frame (VPL GI 'passes')" },
        { key: "seed", type: "int32", default: 0, propargs: {min: 0},
          eval: "C.scene.vpl_gi.seed", visible: "submission",
          description: "Seed of every stochastic choice (VPL GI 'seed')" },
        { key: "auto_parameters", type: "string", default: "off",
          choices: ["off", "time", "error"], visible: "submission",
          description: "Keep 'off' on a farm: 'time'/'error' choose parameters from a cost " +
                       "model measured on each machine, so frames would depend on the worker" },
        { key: "extra_settings", type: "string", default: "", visible: "submission",
          description: "More VPL GI settings as name=python_literal, comma separated, e.g. " +
                       "vpl_count=256, visibility='exact'" },
        { key: "resolution_percentage", type: "int32", default: 0,
          propargs: {min: 0, max: 1000}, visible: "submission",
          description: "Override the resolution percentage (0 = the file's)" },

        { key: "indirect_preview", type: "bool", default: false, visible: "submission",
          description: "Also render a quick preview of the first frame (one pass, 25% size) " +
                       "before the frames, to check the indirect light early" },
    ]
};

function compileJob(job) {
    print("VPL GI render job submitted");
    const settings = job.settings;
    const renderOutput = renderOutputPath(job);
    settings.render_output_path = renderOutput;
    const finalDir = path.dirname(renderOutput);
    const renderDir = intermediatePath(job, finalDir);

    const pinned = pythonExpr(settings, {});
    const renderTasks = [];
    if (settings.indirect_preview) {
        const first = frameChunker(settings.frames, 1)[0];
        const preview = author.Task("preview-indirect", "blender");
        preview.addCommand(blenderCommand(settings,
            pythonExpr(settings, {passes: 1, resolution_percentage: 25}),
            path.join(renderDir, "preview", path.basename(renderOutput)), first));
        renderTasks.push(preview);
    }
    for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
        const task = author.Task(`render-${chunk}`, "blender");
        task.addCommand(blenderCommand(settings, pinned,
            path.join(renderDir, path.basename(renderOutput)), chunk));
        renderTasks.push(task);
    }

    const cleanup = author.Task("move-to-final", "file-management");
    cleanup.addCommand(author.Command("move-directory", {src: renderDir, dest: finalDir}));
    for (const task of renderTasks) {
        cleanup.addDependency(task);
        job.addTask(task);
    }
    job.addTask(cleanup);
}

function blenderCommand(settings, expr, output, chunk) {
    return author.Command("blender-render", {
        exe: settings.blender_cmd,
        argsBefore: [],
        blendfile: settings.blendfile,
        args: [
            "--scene", settings.scene,
            "--python-expr", expr,
            "--render-output", output,
            "--render-format", settings.format,
            // Blender's frame notation: 'a..b' for a range, 'a,b' lists stay as they are.
            "--render-frame", chunk.replace(/-/g, ".."),
        ],
    });
}

// The Python run after the file is opened: engine and settings pinned on every worker.
function pythonExpr(settings, overrides) {
    const pick = (key) => (key in overrides ? overrides[key] : settings[key]);
    const lines = [
        "import bpy",
        "s = bpy.context.scene",
        "s.render.engine = 'VPL_GI'",
        "v = s.vpl_gi",
        // Frames must not depend on the machine or on the chunk: no per-machine cost model,
        // no reuse of the previous frame's VPLs.
        `v.auto_parameters = ${pyString(settings.auto_parameters || "off")}`,
        "v.incremental = False",
        `v.passes = ${integer(pick("passes"), "passes")}`,
        `v.seed = ${integer(pick("seed"), "seed")}`,
    ];
    for (const item of (settings.extra_settings || "").split(",")) {
        if (!item.trim()) continue;
        const match = /^\s*([a-z_][a-z0-9_]*)\s*=\s*(.+?)\s*$/.exec(item);
        if (!match) throw `extra_settings: cannot read '${item}' (use name=value)`;
        if (match[1] == "incremental" || match[1] == "auto_parameters")
            throw `extra_settings: ${match[1]} is pinned by the job type`;
        // bpy lets a misspelt name through as a plain Python attribute, silently lost: look
        // it up first, so that a typo fails the task (KeyError) instead of being ignored.
        lines.push(`v.bl_rna.properties[${pyString(match[1])}]`, `v.${match[1]} = ${match[2]}`);
    }
    const percentage = pick("resolution_percentage");
    if (percentage) lines.push(`s.render.resolution_percentage = ${integer(percentage, "resolution_percentage")}`);
    return lines.join("; ");
}

function integer(value, name) {
    const number = Number(value);
    if (!Number.isInteger(number)) throw `${name}: not an integer: ${value}`;
    return String(number);
}

function pyString(text) {
    return JSON.stringify(String(text));
}

function renderOutputPath(job) {
    const output = job.settings.render_output_path;
    if (!output) throw "no render_output_path setting!";
    return output.replace(/{([^}]+)}/g, (match, group0) =>
        group0 == "timestamp" ? formatTimestampLocal(job.created) : match);
}

function intermediatePath(job, finalDir) {
    const basename = path.basename(finalDir);
    const name = `${basename}__intermediate-${formatTimestampLocal(job.created)}`;
    return path.join(path.dirname(finalDir), name);
}
