//! Open Job Description (the job format AWS Deadline Cloud runs): a job
//! template with a `BakeChunks` step (task parameter `Chunk`, one task per
//! chunk not yet done) and an `Assemble` step that depends on it.
//!
//! The template is written to `<stem>.clips/farm/openjd/template.json`, a
//! folder laid out as a job bundle. The painterly binary, input and output
//! are job parameters of type PATH, so a farm can point them elsewhere or
//! map paths; their values (this binary, the absolute paths given) are in
//! `parameters.json` beside it: `openjd run template.json -p
//! file://parameters.json` runs every step locally. painterly does not submit
//! anything itself, so there is nothing to ask about later: `farm status`
//! reports what the files say.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::{shell_line, FarmJob, Scheduler, Submission, TaskInfo};
use crate::error::{Error, Result};
use crate::usd_io::layer::write_atomic;

/// Step names in the template.
pub const BAKE_STEP: &str = "BakeChunks";
pub const ASSEMBLE_STEP: &str = "Assemble";

/// The Open Job Description "scheduler": writes a template.
pub struct OpenJd;

/// `0-3,5,7-8`: an OpenJD integer range expression of sorted indices.
pub fn range_expression(indices: &[usize]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < indices.len() {
        let mut j = i;
        while j + 1 < indices.len() && indices[j + 1] == indices[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            indices[i].to_string()
        } else {
            format!("{}-{}", indices[i], indices[j])
        });
        i = j + 1;
    }
    parts.join(",")
}

/// The job template for the chunks in `todo` (sorted).
pub fn template(job: &FarmJob, todo: &[usize]) -> Value {
    let action = |args: Vec<String>| {
        let (program, args) = args
            .split_first()
            .map(|(p, a)| (p.clone(), a.to_vec()))
            .unwrap_or_default();
        json!({ "actions": { "onRun": { "command": program, "args": args } } })
    };
    let words = |last: &[&str]| job.command("{{Param.Painterly}}", "{{Param.Input}}", "{{Param.Output}}", last);
    let name = job.output.file_name().unwrap_or_default().to_string_lossy();
    let mut job_name = format!("painterly bake {name}");
    job_name.truncate(job_name.char_indices().nth(128).map_or(job_name.len(), |(i, _)| i));
    let mut steps = Vec::new();
    if !todo.is_empty() {
        steps.push(json!({
            "name": BAKE_STEP,
            "description": "One task per chunk: painterly bake --chunk-index writes that chunk's layer (atomically).",
            "parameterSpace": {
                "taskParameterDefinitions": [
                    { "name": "Chunk", "type": "INT", "range": range_expression(todo) }
                ]
            },
            "script": action(words(&["--chunk-index", "{{Task.Param.Chunk}}"])),
        }));
    }
    let mut assemble = json!({
        "name": ASSEMBLE_STEP,
        "description": "Checks every chunk (missing or stale ones fail the step) and writes the clip set.",
        "script": action(words(&["--assemble"])),
    });
    if !todo.is_empty() {
        assemble["dependencies"] = json!([{ "dependsOn": BAKE_STEP }]);
    }
    steps.push(assemble);
    let path = |p: &Path| p.to_string_lossy().into_owned();
    json!({
        "specificationVersion": "jobtemplate-2023-09",
        "name": job_name,
        "description": format!(
            "Written by `painterly farm submit --scheduler openjd`: {} chunks of {} frames of {}, {} to bake.",
            job.clips.chunks.len(), job.chunk_size, path(&job.output), todo.len()
        ),
        // No defaults: OpenJD PATH defaults must lie inside the template's
        // folder. The values are in parameters.json beside it.
        "parameterDefinitions": [
            { "name": "Painterly", "type": "PATH", "objectType": "FILE",
              "description": "The painterly binary every task runs." },
            { "name": "Input", "type": "PATH", "objectType": "FILE",
              "description": "The painted character." },
            { "name": "Output", "type": "PATH", "objectType": "FILE",
              "description": "The clip-set layer; chunks go to its <stem>.clips/ folder." }
        ],
        "steps": steps,
    })
}

/// The folder the template is written to (a job bundle).
pub fn template_dir(job: &FarmJob) -> PathBuf {
    job.farm_dir().join("openjd")
}

/// The job parameter values of `job`, as `openjd run -p file://…` reads them.
pub fn parameters(job: &FarmJob) -> Value {
    let path = |p: &Path| p.to_string_lossy().into_owned();
    json!({
        "Painterly": path(&job.painterly),
        "Input": path(&job.input),
        "Output": path(&job.output),
    })
}

impl Scheduler for OpenJd {
    fn submit(&self, job: &FarmJob, todo: &[usize]) -> Result<Submission> {
        let dir = template_dir(job);
        std::fs::create_dir_all(&dir)
            .map_err(|e| Error::msg(format!("cannot create the template folder: {e}")).in_file(&dir))?;
        let path = dir.join("template.json");
        let params = dir.join("parameters.json");
        for (file, value) in [(&path, template(job, todo)), (&params, parameters(job))] {
            let text = serde_json::to_string_pretty(&value).map_err(|e| Error::msg(format!("internal: {e}")))?;
            write_atomic(file, format!("{text}\n").as_bytes())?;
        }

        Ok(Submission {
            job: None,
            tasks: todo.iter().map(|&k| (k, format!("{BAKE_STEP}[Chunk={k}]"))).collect(),
            assemble_job: Some(ASSEMBLE_STEP.to_string()),
            next: Some(shell_line(&[
                "openjd".into(),
                "run".into(),
                path.to_string_lossy().into_owned(),
                "-p".into(),
                format!("file://{}", params.display()),
            ])),
            files: vec![path, params],
            commands: Vec::new(),
        })
    }

    fn query(&self, _ids: &[String]) -> Option<HashMap<String, TaskInfo>> {
        None
    }

    fn cancel_hint(&self, _id: &str) -> String {
        "stop the openjd run".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_expressions_compress_runs() {
        assert_eq!(range_expression(&[0, 1, 2, 3]), "0-3");
        assert_eq!(range_expression(&[2]), "2");
        assert_eq!(range_expression(&[0, 2, 3, 4, 7, 9, 10]), "0,2-4,7,9-10");
        assert_eq!(range_expression(&[]), "");
    }
}
