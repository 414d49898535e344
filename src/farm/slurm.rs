//! Slurm: the chunk tasks as one job array, the assembly as a job that
//! depends on it (`--dependency=afterok:ARRAY --kill-on-invalid-dep=yes`,
//! so a failed or cancelled chunk cancels the assembly instead of leaving
//! it pending forever).
//!
//! Only chunks that are not done are submitted: array index `i` bakes chunk
//! `CHUNKS[i]` of the generated script, so indices stay small (Slurm's
//! MaxArraySize) whichever chunks remain. Scripts and logs go to
//! `<stem>.clips/farm/`. Task states come from `squeue` (which also lists
//! jobs that ended within the cluster's MinJobAge) and, where accounting
//! is enabled, `sacct`.

use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use super::{find_on_path, run_tool, shell_line, FarmJob, Scheduler, Submission, TaskInfo, TaskState};
use crate::error::{Error, Result};
use crate::usd_io::layer::write_atomic;

/// How long sbatch/squeue/scancel may take before painterly gives up.
const TOOL_LIMIT: Duration = Duration::from_secs(60);

/// A task uses as many threads as CPUs Slurm gave it (rayon reads
/// RAYON_NUM_THREADS; 0 means all), unless the submitter set the variable:
/// without CPU binding on the node, every task would otherwise start a
/// thread per core.
const THREADS: &str = "export RAYON_NUM_THREADS=\"${RAYON_NUM_THREADS:-${SLURM_CPUS_ON_NODE:-0}}\"";

/// The Slurm scheduler, with the options given to `farm submit`.
pub struct Slurm {
    pub partition: Option<String>,
    /// Extra sbatch arguments (`--sbatch-arg`), for every job.
    pub extra: Vec<String>,
}

/// Checks sbatch is on PATH.
pub fn check_installed() -> Result<()> {
    if find_on_path("sbatch").is_none() {
        return Err(Error::msg(
            "sbatch not found on PATH: run farm submit on a Slurm submit host (Debian: apt-get install slurm-client), or use --scheduler openjd",
        ));
    }
    Ok(())
}

impl Slurm {
    /// sbatch options every job gets.
    fn common(&self, job: &FarmJob) -> Vec<String> {
        let mut a = vec![
            "sbatch".to_string(),
            "--parsable".into(),
            format!("--chdir={}", job.farm_dir().display()),
        ];
        if let Some(p) = &self.partition {
            a.push(format!("--partition={p}"));
        }
        a
    }

    /// Runs one sbatch; its job id, or sbatch's own complaint.
    fn sbatch(&self, mut argv: Vec<String>, script: &Path, what: &str) -> Result<(String, Vec<String>)> {
        argv.extend(self.extra.iter().cloned());
        argv.push(script.to_string_lossy().into_owned());
        let out = run_tool(&argv, TOOL_LIMIT)?;
        if out.code != Some(0) {
            return Err(Error::msg(format!(
                "sbatch refused the {what}: {}\n  command: {}",
                first_lines(&out.stderr, &out.stdout),
                shell_line(&argv)
            )));
        }
        // --parsable prints "ID" or "ID;CLUSTER".
        let id = out
            .stdout
            .lines()
            .next()
            .unwrap_or("")
            .split(';')
            .next()
            .unwrap_or("")
            .trim();
        if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
            return Err(Error::msg(format!(
                "sbatch printed no job id for the {what} (stdout {:?})",
                out.stdout.trim()
            )));
        }
        Ok((id.to_string(), argv))
    }
}

/// sbatch's message: stderr, else stdout, at most a few lines.
fn first_lines(stderr: &str, stdout: &str) -> String {
    let text = if stderr.trim().is_empty() { stdout } else { stderr };
    let lines: Vec<&str> = text.trim().lines().take(6).collect();
    if lines.is_empty() {
        "(no message)".into()
    } else {
        lines.join("\n  ")
    }
}

fn script(lines: &[String]) -> String {
    let mut s = lines.join("\n");
    s.push('\n');
    s
}

/// The logs folder as part of an sbatch `--output` pattern, where `%`
/// starts a replacement symbol and `%%` stands for itself.
fn log_pattern_dir(logs: &std::path::Path) -> String {
    logs.display().to_string().replace('%', "%%")
}

impl Scheduler for Slurm {
    fn submit(&self, job: &FarmJob, todo: &[usize]) -> Result<Submission> {
        let dir = job.farm_dir();
        let logs = dir.join("logs");
        let stem = job
            .output
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let mut sub = Submission::default();
        if !todo.is_empty() {
            let chunks: Vec<String> = todo.iter().map(|k| k.to_string()).collect();
            let path = dir.join("bake.sh");
            let body = script(&[
                "#!/bin/bash".into(),
                format!(
                    "# painterly farm: a Slurm array task bakes one chunk of {:?} (written by `painterly farm submit`).",
                    job.output
                ),
                "# Array index i bakes chunk CHUNKS[i]: only chunks not already done were submitted.".into(),
                "set -euo pipefail".into(),
                THREADS.into(),
                format!("CHUNKS=({})", chunks.join(" ")),
                "K=${CHUNKS[$SLURM_ARRAY_TASK_ID]}".into(),
                "echo \"painterly farm: chunk $K (array task $SLURM_ARRAY_TASK_ID of job $SLURM_ARRAY_JOB_ID)\"".into(),
                format!("exec {} \"$K\"", shell_line(&job.chunk_command_head())),
            ]);
            write_atomic(&path, body.as_bytes())?;
            sub.files.push(path.clone());
            let mut argv = self.common(job);
            argv.extend([
                format!("--job-name=painterly-bake:{stem}"),
                format!("--array=0-{}", todo.len() - 1),
                format!("--output={}/bake.%A_%a.log", log_pattern_dir(&logs)),
            ]);
            let (id, argv) = self.sbatch(argv, &path, "chunk tasks")?;
            sub.tasks = todo
                .iter()
                .enumerate()
                .map(|(i, &k)| (k, format!("{id}_{i}")))
                .collect();
            sub.job = Some(id);
            sub.commands.push(argv);
        }
        let path = dir.join("assemble.sh");
        let body = script(&[
            "#!/bin/bash".into(),
            format!(
                "# painterly farm: checks every chunk of {:?} and writes the clip set (written by `painterly farm submit`).",
                job.output
            ),
            "set -euo pipefail".into(),
            THREADS.into(),
            format!("exec {}", shell_line(&job.assemble_command())),
        ]);
        write_atomic(&path, body.as_bytes())?;
        sub.files.push(path.clone());
        let mut argv = self.common(job);
        argv.extend([
            format!("--job-name=painterly-assemble:{stem}"),
            format!("--output={}/assemble.%j.log", log_pattern_dir(&logs)),
        ]);
        if let Some(id) = &sub.job {
            argv.extend([format!("--dependency=afterok:{id}"), "--kill-on-invalid-dep=yes".into()]);
        }
        match self.sbatch(argv, &path, "assembly job") {
            Ok((id, argv)) => {
                sub.assemble_job = Some(id);
                sub.commands.push(argv);
            }
            Err(e) => {
                // Without its assembly the submission is incomplete: take
                // the chunk tasks back so a re-submit starts clean.
                let Some(array) = &sub.job else { return Err(e) };
                let cancel = ["scancel".to_string(), array.clone()];
                let undone = match run_tool(&cancel, TOOL_LIMIT) {
                    Ok(o) if o.code == Some(0) => format!("the chunk tasks (job {array}) were cancelled"),
                    _ => format!("cancelling the chunk tasks failed: run scancel {array}"),
                };
                return Err(Error::msg(format!("{}; {undone}", e.message)));
            }
        }
        Ok(sub)
    }

    fn query(&self, ids: &[String]) -> Option<HashMap<String, TaskInfo>> {
        if ids.is_empty() || find_on_path("squeue").is_none() {
            return None;
        }
        // Jobs of array tasks: "12_3" belongs to job 12.
        let mut jobs: Vec<&str> = ids.iter().map(|i| i.split('_').next().unwrap_or(i)).collect();
        jobs.sort_unstable();
        jobs.dedup();
        let mut known = HashMap::new();
        if find_on_path("sacct").is_some() {
            // Accounting keeps every job; when the cluster has none, sacct fails and squeue answers alone.
            let argv = vec![
                "sacct".to_string(),
                "-n".into(),
                "-P".into(),
                "-X".into(),
                format!("--jobs={}", jobs.join(",")),
                "--format=JobID,State,Reason".into(),
            ];
            if let Ok(out) = run_tool(&argv, TOOL_LIMIT) {
                if out.code == Some(0) {
                    parse_into(&out.stdout, &mut known);
                }
            }
        }
        let argv = vec![
            "squeue".to_string(),
            "-h".into(),
            "-r".into(),
            "--states=all".into(),
            format!("--jobs={}", jobs.join(",")),
            "--format=%i|%T|%r".into(),
        ];
        let out = run_tool(&argv, TOOL_LIMIT).ok()?;
        match out.code {
            Some(0) => parse_into(&out.stdout, &mut known),
            // Every job has left the controller's memory: nothing is live.
            _ if out.stderr.contains("Invalid job id") => {}
            _ => return None,
        }
        Some(known)
    }

    fn cancel_hint(&self, id: &str) -> String {
        format!("scancel {id}")
    }
}

/// Parses `ID|STATE|REASON` lines (squeue and sacct print the same shape)
/// into `known`; later lines win, so squeue's live view overrides sacct.
fn parse_into(text: &str, known: &mut HashMap<String, TaskInfo>) {
    for line in text.lines() {
        let mut f = line.split('|');
        let (Some(id), Some(raw)) = (f.next(), f.next()) else {
            continue;
        };
        // sacct says "CANCELLED by 0".
        let raw = raw.split_whitespace().next().unwrap_or("").to_string();
        let reason = f
            .next()
            .map(str::trim)
            .filter(|r| !r.is_empty() && *r != "None" && *r != "(null)")
            .map(str::to_string);
        let state = match raw.as_str() {
            "PENDING" | "REQUEUED" | "REQUEUE_HOLD" | "REQUEUE_FED" | "RESV_DEL_HOLD" | "SUSPENDED" | "STOPPED" => {
                TaskState::Pending
            }
            "RUNNING" | "CONFIGURING" | "COMPLETING" | "RESIZING" | "SIGNALING" | "STAGE_OUT" => TaskState::Running,
            "COMPLETED" => TaskState::Completed,
            "" => continue,
            _ => TaskState::Failed,
        };
        known.insert(id.trim().to_string(), TaskInfo { state, raw, reason });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn squeue_lines_parse_to_task_states() {
        let mut known = HashMap::new();
        parse_into(
            "12_0|COMPLETED|None\n12_1|RUNNING|None\n12_2|PENDING|Resources\n12_3|CANCELLED|None\n13|CANCELLED|DependencyNeverSatisfied\n14|OUT_OF_MEMORY|None\n",
            &mut known,
        );
        let s = |id: &str| known[id].state;
        assert_eq!(s("12_0"), TaskState::Completed);
        assert_eq!(s("12_1"), TaskState::Running);
        assert_eq!(s("12_2"), TaskState::Pending);
        assert_eq!(known["12_2"].reason.as_deref(), Some("Resources"));
        assert_eq!(s("12_3"), TaskState::Failed);
        assert_eq!(known["12_3"].reason, None);
        assert_eq!(known["13"].reason.as_deref(), Some("DependencyNeverSatisfied"));
        assert_eq!(s("14"), TaskState::Failed);
        // sacct's "CANCELLED by 0", and a later squeue line wins.
        parse_into("12_1|CANCELLED by 0|None\n", &mut known);
        assert_eq!(known["12_1"].state, TaskState::Failed);
        assert_eq!(known["12_1"].raw, "CANCELLED");
    }

    #[test]
    fn a_line_without_a_state_says_nothing() {
        // `ID|STATE|REASON` with an empty STATE field (or one of blanks) names
        // no state: the task is not recorded, and an earlier line's state
        // (sacct's, before squeue's) stands.
        let mut known = HashMap::new();
        parse_into("20_0|COMPLETED|None\n", &mut known);
        parse_into("20_0||None\n20_1| |None\n21||\n", &mut known);
        assert_eq!(known.len(), 1, "{known:?}");
        assert_eq!(known["20_0"].state, TaskState::Completed);
        assert_eq!(known["20_0"].raw, "COMPLETED");
    }
}
