//! `farm status`: what the plan, the chunk stamps and the scheduler say.
//!
//! A chunk is `done` when its layer is on disk and stamped with the input's
//! current hash, this painterly version and its frames, whatever any task
//! says. Otherwise the scheduler decides when it can be asked: `pending`
//! or `running` while its task waits or runs, `failed` when its task ended
//! (or is no longer known) without leaving a current chunk. Without a
//! scheduler to ask, the files alone answer: `missing` or `stale`.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::plan::{plan_path_for_output, state_word, FarmPlan};
use super::{absolute, SchedulerKind, TaskInfo, TaskState};
use crate::error::{Error, Result};
use crate::frames::FrameRange;
use crate::usd_io::bake_layer::read_provenance;
use crate::usd_io::clips::{self, clip_set_status, ChunkState, ClipPlan};
use crate::usd_io::stage::StageReader;

/// The status of a farm bake (`farm status --json` prints it as is).
#[derive(Debug, Serialize)]
pub struct FarmStatus {
    pub output: PathBuf,
    pub plan: PathBuf,
    pub input: PathBuf,
    pub scheduler: SchedulerKind,
    pub submitted_at: String,
    /// Whether the scheduler answered (it keeps live state, its commands
    /// are on PATH and the query succeeded); when false, states come from
    /// the files alone.
    pub scheduler_queried: bool,
    /// The input's layers changed since the submission (chunks baked from
    /// the old input are stale).
    pub input_changed: bool,
    pub chunk_size: usize,
    pub job: Option<String>,
    pub chunks: Vec<ChunkStatus>,
    pub counts: Counts,
    pub assembly: AssemblyStatus,
    /// The clip set is on disk, lists exactly these chunks, and was
    /// assembled for the current input.
    pub assembled: bool,
    /// Every chunk done and the clip set assembled (exit 0).
    pub complete: bool,
}

/// One chunk.
#[derive(Debug, Serialize)]
pub struct ChunkStatus {
    pub index: usize,
    pub name: String,
    pub path: PathBuf,
    pub frames: String,
    /// done, running, pending, failed, missing or stale.
    pub state: &'static str,
    /// The scheduler's id of its latest task (none when it was already done).
    pub task: Option<String>,
    /// The scheduler's own word for the task's state, when asked.
    pub scheduler_state: Option<String>,
    /// Why: the scheduler's reason, or what is wrong with the file.
    pub detail: Option<String>,
}

/// How many chunks are in each state.
#[derive(Debug, Default, Serialize)]
pub struct Counts {
    pub done: usize,
    pub running: usize,
    pub pending: usize,
    pub failed: usize,
    pub missing: usize,
    pub stale: usize,
}

/// The assembly task.
#[derive(Debug, Serialize)]
pub struct AssemblyStatus {
    pub job: Option<String>,
    /// done (clip set assembled), running, pending, failed or missing.
    pub state: &'static str,
    pub scheduler_state: Option<String>,
    pub detail: Option<String>,
}

/// The status of the farm bake whose clip-set layer is `output`.
pub fn status(output: &Path) -> Result<FarmStatus> {
    let plan_path = plan_path_for_output(output);
    let plan = FarmPlan::read_if_any(&plan_path)?.ok_or_else(|| {
        Error::msg(format!(
            "no farm plan at {}: was this output submitted with painterly farm submit?",
            plan_path.display()
        ))
        .in_file(output)
    })?;
    let output = absolute(output)?;
    let range: FrameRange = plan
        .frame_range
        .parse()
        .map_err(|e| Error::msg(format!("frame_range {:?}: {e}", plan.frame_range)).in_file(&plan_path))?;
    let times = range.times();
    let clips = ClipPlan::new(&output, &times, plan.chunk_size)?;
    let names_match =
        clips.chunks.len() == plan.chunks.len() && clips.chunks.iter().zip(&plan.chunks).all(|(a, b)| a.name == b.name);
    if !names_match {
        return Err(Error::msg("the plan's chunks do not match its frames and chunk size").in_file(&plan_path));
    }
    let reader = StageReader::open(&plan.input)
        .map_err(|e| Error::msg(format!("cannot open the farm bake's input: {}", e.message)).in_file(&plan.input))?;
    let hash = clips::input_hash(&reader)?;
    let options = crate::bake::options_text(plan.bake_proxy, plan.camera.as_deref());
    let states = clips::chunk_states(&clips, &hash, options.as_deref(), &times)?;

    let scheduler = plan.scheduler.scheduler(None);
    let known = scheduler.query(&plan.task_ids());
    let info = |id: &Option<String>| -> Option<&TaskInfo> { id.as_ref().and_then(|i| known.as_ref()?.get(i)) };

    let mut counts = Counts::default();
    let chunks: Vec<ChunkStatus> = plan
        .chunks
        .iter()
        .zip(&states)
        .map(|(c, file)| {
            let task = info(&c.task);
            let (state, detail) = chunk_state(file, c.task.as_deref(), task, known.is_some());
            match state {
                "done" => counts.done += 1,
                "running" => counts.running += 1,
                "pending" => counts.pending += 1,
                "failed" => counts.failed += 1,
                "missing" => counts.missing += 1,
                _ => counts.stale += 1,
            }
            ChunkStatus {
                index: c.index,
                name: c.name.clone(),
                path: clips.chunk_path(&clips.chunks[c.index]),
                frames: c.frames.clone(),
                state,
                task: c.task.clone(),
                scheduler_state: task.map(|t| t.raw.clone()),
                detail,
            }
        })
        .collect();

    // Assembled: the clip set on disk was written for this input and lists
    // exactly the plan's chunks, and every one of them is done.
    let provenance = if output.is_file() {
        read_provenance(&output).ok().flatten()
    } else {
        None
    };
    let assembled = provenance.as_ref().is_some_and(|p| {
        p.input_hash.as_deref() == Some(hash.as_str())
            && p.options == options
            && p.chunks.as_ref().is_some_and(|(size, names)| {
                *size == plan.chunk_size && names.iter().eq(plan.chunks.iter().map(|c| &c.name))
            })
    }) && clip_set_status(&output, Some(&hash))?
        .is_some_and(|s| s.chunks.iter().all(|(_, st)| *st == ChunkState::Done));
    let all_done = counts.done == chunks.len();
    let asm = info(&plan.assemble_job);
    let assembly = assembly_state(
        assembled,
        provenance.is_some(),
        plan.assemble_job.clone(),
        asm,
        known.is_some(),
    );
    let complete = all_done && assembled && assembly.state == "done";
    Ok(FarmStatus {
        // The plan beside the absolute output, not as typed.
        plan: plan_path_for_output(&output),
        output,
        input: plan.input.clone(),
        scheduler: plan.scheduler,
        submitted_at: plan.submitted_at.clone(),
        scheduler_queried: known.is_some(),
        input_changed: hash != plan.input_hash,
        chunk_size: plan.chunk_size,
        job: plan.job.clone(),
        chunks,
        counts,
        assembly,
        assembled,
        complete,
    })
}

/// A chunk's state from its file and its task.
fn chunk_state(
    file: &ChunkState,
    id: Option<&str>,
    task: Option<&TaskInfo>,
    queried: bool,
) -> (&'static str, Option<String>) {
    let reason = |t: &TaskInfo| t.reason.clone();
    match (file, task) {
        // A task that waits or runs will still write the chunk, even over a
        // current file (one a local bake wrote meanwhile): not done yet.
        (_, Some(t)) if t.state == TaskState::Pending => ("pending", reason(t)),
        (_, Some(t)) if t.state == TaskState::Running => ("running", reason(t)),
        (ChunkState::Done, _) => ("done", None),
        (file, Some(t)) => (
            "failed",
            Some(format!(
                "task {} ended {}{} and the chunk is {}",
                id.unwrap_or("?"),
                t.raw,
                t.reason.as_ref().map(|r| format!(" ({r})")).unwrap_or_default(),
                file_word(file)
            )),
        ),
        (file, None) if queried && id.is_some() => (
            "failed",
            Some(format!(
                "task {} is no longer known to the scheduler and the chunk is {}",
                id.unwrap_or("?"),
                file_word(file)
            )),
        ),
        (ChunkState::Stale(why), None) => ("stale", Some(why.clone())),
        (file, None) => (state_word(file), None),
    }
}

fn file_word(file: &ChunkState) -> String {
    match file {
        ChunkState::Stale(why) => format!("stale: {why}"),
        other => state_word(other).to_string(),
    }
}

fn assembly_state(
    assembled: bool,
    clip_set_exists: bool,
    job: Option<String>,
    task: Option<&TaskInfo>,
    queried: bool,
) -> AssemblyStatus {
    let (state, detail) = match task {
        // A live assembly task will write the clip set again.
        Some(t) if t.state == TaskState::Pending => ("pending", t.reason.clone()),
        Some(t) if t.state == TaskState::Running => ("running", t.reason.clone()),
        _ if assembled => ("done", None),
        Some(t) => (
            "failed",
            Some(format!(
                "ended {}{} without a current clip set",
                t.raw,
                t.reason.as_ref().map(|r| format!(" ({r})")).unwrap_or_default()
            )),
        ),
        None if queried && job.is_some() => (
            "failed",
            Some("no longer known to the scheduler, and the clip set is not assembled".to_string()),
        ),
        None if clip_set_exists => (
            "missing",
            Some("the clip set on disk is not current: missing or stale chunks, or another input".to_string()),
        ),
        None => ("missing", None),
    };
    AssemblyStatus {
        job,
        state,
        scheduler_state: task.map(|t| t.raw.clone()),
        detail,
    }
}

impl FarmStatus {
    /// The human-readable report.
    pub fn to_text(&self) -> String {
        let scheduler = serde_json::to_value(self.scheduler)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let mut s = format!(
            "{}: {} chunks of {} frames, {}{}, submitted {}\n",
            self.output.display(),
            self.chunks.len(),
            self.chunk_size,
            scheduler,
            self.job.as_ref().map(|j| format!(" job {j}")).unwrap_or_default(),
            self.submitted_at
        );
        if self.scheduler == crate::farm::SchedulerKind::Openjd {
            // Nothing to ask: an Open Job Description job runs elsewhere.
            s += "  (states come from the files)\n";
        } else if !self.scheduler_queried {
            s += "  (no answer from the scheduler, not on PATH or not reachable: states come from the files)\n";
        }
        if self.input_changed {
            s += "  (the input changed since the submission)\n";
        }
        let width = self.chunks.iter().map(|c| c.name.len()).max().unwrap_or(0);
        for c in &self.chunks {
            let mut line = format!("  {:<width$}  {:<8}", c.name, c.state);
            if let (Some(t), true) = (&c.task, c.state != "done") {
                line += &format!(" task {t}");
            }
            if let Some(d) = &c.detail {
                line += &format!(" ({d})");
            }
            s += line.trim_end();
            s.push('\n');
        }
        let a = &self.assembly;
        s += &format!(
            "  assembly: {}{}{}\n",
            a.state,
            a.job.as_ref().map(|j| format!(" (job {j})")).unwrap_or_default(),
            a.detail.as_ref().map(|d| format!(": {d}")).unwrap_or_default()
        );
        let n = &self.counts;
        s += &format!(
            "{} done, {} running, {} pending, {} failed, {} missing, {} stale; clip set {}\n",
            n.done,
            n.running,
            n.pending,
            n.failed,
            n.missing,
            n.stale,
            if self.assembled { "assembled" } else { "not assembled" }
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn task(state: TaskState, raw: &str) -> TaskInfo {
        TaskInfo {
            state,
            raw: raw.into(),
            reason: None,
        }
    }

    #[test]
    fn a_chunk_on_disk_is_done_unless_its_task_still_waits_or_runs() {
        let t = task(TaskState::Failed, "CANCELLED");
        assert_eq!(chunk_state(&ChunkState::Done, Some("1_0"), Some(&t), true).0, "done");
        // A live task will write the chunk again (a local bake finished it
        // meanwhile): status said done and the shot complete while the farm
        // was still to rewrite it (a review, 2026-12-07).
        for (state, raw, word) in [
            (TaskState::Pending, "PENDING", "pending"),
            (TaskState::Running, "RUNNING", "running"),
        ] {
            let live = task(state, raw);
            assert_eq!(chunk_state(&ChunkState::Done, Some("1_0"), Some(&live), true).0, word);
        }
    }

    #[test]
    fn a_missing_chunk_takes_its_tasks_state() {
        let m = ChunkState::Missing;
        let pending = task(TaskState::Pending, "PENDING");
        let running = task(TaskState::Running, "RUNNING");
        let cancelled = task(TaskState::Failed, "CANCELLED");
        let completed = task(TaskState::Completed, "COMPLETED");
        assert_eq!(chunk_state(&m, Some("1_0"), Some(&pending), true).0, "pending");
        assert_eq!(chunk_state(&m, Some("1_0"), Some(&running), true).0, "running");
        let (s, d) = chunk_state(&m, Some("1_0"), Some(&cancelled), true);
        assert_eq!(
            (s, d.unwrap().as_str()),
            ("failed", "task 1_0 ended CANCELLED and the chunk is missing")
        );
        // A task that succeeded without leaving a current chunk failed too.
        assert_eq!(chunk_state(&m, Some("1_0"), Some(&completed), true).0, "failed");
        assert_eq!(chunk_state(&m, Some("1_0"), None, true).0, "failed");
        // Without the scheduler, or without a task, the file answers.
        assert_eq!(chunk_state(&m, Some("1_0"), None, false).0, "missing");
        assert_eq!(chunk_state(&m, None, None, true).0, "missing");
        let stale = ChunkState::Stale("baked from a different input".into());
        assert_eq!(chunk_state(&stale, None, None, false).0, "stale");
    }

    #[test]
    fn the_assembly_takes_its_tasks_state_until_the_clip_set_is_assembled() {
        let mut pending = task(TaskState::Pending, "PENDING");
        pending.reason = Some("Dependency".into());
        let running = task(TaskState::Running, "RUNNING");
        let mut cancelled = task(TaskState::Failed, "CANCELLED");
        cancelled.reason = Some("DependencyNeverSatisfied".into());
        let completed = task(TaskState::Completed, "COMPLETED");
        let job = || Some("7".to_string());
        let got = |a: AssemblyStatus| (a.state, a.scheduler_state, a.detail);
        let s = |x: &str| Some(x.to_string());
        // Assembled is done whatever an ended task says, but its word is kept.
        assert_eq!(
            got(assembly_state(true, true, job(), Some(&cancelled), true)),
            ("done", s("CANCELLED"), None)
        );
        // A live assembly task will write the clip set again.
        assert_eq!(
            got(assembly_state(true, true, job(), Some(&pending), true)),
            ("pending", s("PENDING"), s("Dependency"))
        );
        assert_eq!(
            got(assembly_state(false, true, job(), Some(&pending), true)),
            ("pending", s("PENDING"), s("Dependency"))
        );
        assert_eq!(
            got(assembly_state(false, true, job(), Some(&running), true)),
            ("running", s("RUNNING"), None)
        );
        assert_eq!(
            got(assembly_state(false, false, job(), Some(&cancelled), true)),
            (
                "failed",
                s("CANCELLED"),
                s("ended CANCELLED (DependencyNeverSatisfied) without a current clip set")
            )
        );
        assert_eq!(
            got(assembly_state(false, false, job(), Some(&completed), true)),
            (
                "failed",
                s("COMPLETED"),
                s("ended COMPLETED without a current clip set")
            )
        );
        assert_eq!(
            got(assembly_state(false, false, job(), None, true)),
            (
                "failed",
                None,
                s("no longer known to the scheduler, and the clip set is not assembled")
            )
        );
        let stale = "the clip set on disk is not current: missing or stale chunks, or another input";
        // Not asked, or no assembly task to ask about: the files answer.
        assert_eq!(
            got(assembly_state(false, true, job(), None, false)),
            ("missing", None, s(stale))
        );
        assert_eq!(
            got(assembly_state(false, true, None, None, true)),
            ("missing", None, s(stale))
        );
        assert_eq!(
            got(assembly_state(false, false, job(), None, false)),
            ("missing", None, None)
        );
    }

    #[test]
    fn the_text_report_has_a_line_per_chunk_and_the_counts() {
        let chunk = |index: usize, name: &str, state: &'static str, detail: Option<&str>| ChunkStatus {
            index,
            name: name.into(),
            path: PathBuf::from("/x/shot.clips").join(name),
            frames: String::new(),
            state,
            task: Some(format!("4242_{index}")),
            scheduler_state: None,
            detail: detail.map(str::to_string),
        };
        let st = FarmStatus {
            output: "/x/shot.usda".into(),
            plan: "/x/shot.clips/farm/plan.json".into(),
            input: "/x/in.usda".into(),
            scheduler: SchedulerKind::Slurm,
            submitted_at: "2026-12-03T20:00:00Z".into(),
            scheduler_queried: false,
            input_changed: true,
            chunk_size: 12,
            job: Some("4242".into()),
            chunks: vec![
                chunk(0, "shot.0000.1-12.usdc", "done", None),
                chunk(1, "shot.0001.13-24.usdc", "failed", Some("why")),
            ],
            counts: Counts {
                done: 1,
                failed: 1,
                ..Counts::default()
            },
            assembly: AssemblyStatus {
                job: Some("4243".into()),
                state: "pending",
                scheduler_state: None,
                detail: Some("Dependency".into()),
            },
            assembled: false,
            complete: false,
        };
        // Names padded to the longest (20 characters), states to 8; a done
        // chunk's task is not shown.
        assert_eq!(
            st.to_text(),
            "/x/shot.usda: 2 chunks of 12 frames, slurm job 4242, submitted 2026-12-03T20:00:00Z\n\
             \x20 (no answer from the scheduler, not on PATH or not reachable: states come from the files)\n\
             \x20 (the input changed since the submission)\n\
             \x20 shot.0000.1-12.usdc   done\n\
             \x20 shot.0001.13-24.usdc  failed   task 4242_1 (why)\n\
             \x20 assembly: pending (job 4243): Dependency\n\
             1 done, 0 running, 0 pending, 1 failed, 0 missing, 0 stale; clip set not assembled\n"
        );
        // Open Job Description: no scheduler to ask, so no "no answer".
        let openjd = FarmStatus {
            scheduler: crate::farm::SchedulerKind::Openjd,
            job: None,
            ..st
        };
        let text = openjd.to_text();
        let lines: Vec<&str> = text.lines().take(2).collect();
        assert_eq!(
            lines,
            [
                "/x/shot.usda: 2 chunks of 12 frames, openjd, submitted 2026-12-03T20:00:00Z",
                "  (states come from the files)"
            ]
        );
    }
}
