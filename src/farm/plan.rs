//! The plan file of a farm submission: `<stem>.clips/farm/plan.json`.
//!
//! Written by `farm submit` (atomically, after the scheduler accepted the
//! jobs) and read by `farm status` and by the next `farm submit`. It holds
//! everything needed to answer later without the submitting process: the
//! input, frames and chunk size, the exact command of every task, the
//! painterly binary they run, the scheduler's ids per chunk, and when.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use super::{farm_dir, FarmJob, SchedulerKind, Submission};
use crate::error::{Error, Result};
use crate::usd_io::clips::{ChunkState, ClipPlan};
use crate::usd_io::layer::write_atomic;

/// The plan file's `format` value; bumped when fields change meaning.
pub const FORMAT: &str = "painterly-farm-plan 1";

/// A submission, as recorded beside the chunks.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FarmPlan {
    /// [`FORMAT`].
    pub format: String,
    pub scheduler: SchedulerKind,
    /// Absolute paths.
    pub input: PathBuf,
    pub output: PathBuf,
    /// SHA-256 of the input's layers at submission (see `clips::input_hash`).
    pub input_hash: String,
    /// The painterly binary every task runs, and its version.
    pub painterly: PathBuf,
    pub version: String,
    /// `--frames` as given to `farm submit`, or null for the stage's range.
    pub frames: Option<String>,
    /// The frames baked, resolved: `A:B:STEP`.
    pub frame_range: String,
    pub frame_count: usize,
    pub chunk_size: usize,
    pub camera: Option<String>,
    pub bake_proxy: bool,
    /// Submission time, UTC, RFC 3339.
    pub submitted_at: String,
    /// The scheduler's id of the chunk tasks as a whole (Slurm: the array job).
    pub job: Option<String>,
    /// The assembly task's id.
    pub assemble_job: Option<String>,
    /// The assembly task's command, exactly.
    pub assemble_command: Vec<String>,
    /// The submission commands run (e.g. sbatch …), exactly.
    pub submit_commands: Vec<Vec<String>>,
    /// Job scripts or templates written.
    pub files: Vec<PathBuf>,
    pub chunks: Vec<PlanChunk>,
}

/// One chunk in the plan.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PlanChunk {
    pub index: usize,
    /// File name in the clips folder.
    pub name: String,
    /// The chunk's frames, `A:B:STEP`.
    pub frames: String,
    /// Its state when submitted: done (skipped), missing or stale.
    pub state_at_submit: String,
    /// Whether this submission queued a task for it.
    pub submitted: bool,
    /// The scheduler's id of its task.
    pub task: Option<String>,
    /// The task's command, exactly.
    pub command: Vec<String>,
}

/// Where a clip plan's farm plan lives.
pub fn plan_path(clips: &ClipPlan) -> PathBuf {
    farm_dir(clips).join("plan.json")
}

/// The plan path for a clip-set output path, without knowing its chunks.
pub fn plan_path_for_output(output: &Path) -> PathBuf {
    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
    output
        .with_file_name(format!("{stem}.clips"))
        .join("farm")
        .join("plan.json")
}

impl FarmPlan {
    /// The plan of a submission.
    pub fn new(scheduler: SchedulerKind, job: &FarmJob, sub: &Submission) -> FarmPlan {
        let step = crate::usd_io::clips::frame_step(&job.times);
        let tasks: std::collections::HashMap<usize, &String> = sub.tasks.iter().map(|(k, id)| (*k, id)).collect();
        let chunks = job
            .clips
            .chunks
            .iter()
            .zip(&job.states)
            .map(|(c, state)| {
                let task = tasks.get(&c.index).map(|id| (*id).clone());
                PlanChunk {
                    index: c.index,
                    name: c.name.clone(),
                    frames: format!("{}:{}:{}", job.times[c.start], job.times[c.end - 1], step),
                    state_at_submit: state_word(state).to_string(),
                    submitted: task.is_some(),
                    task,
                    command: job.chunk_command(c.index),
                }
            })
            .collect();
        let r = job.frame_range;
        FarmPlan {
            format: FORMAT.to_string(),
            scheduler,
            input: job.input.clone(),
            output: job.output.clone(),
            input_hash: job.input_hash.clone(),
            painterly: job.painterly.clone(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            frames: job.frames.map(|f| format!("{}:{}:{}", f.start, f.end, f.step)),
            frame_range: format!("{}:{}:{}", r.start, r.end, r.step),
            frame_count: job.times.len(),
            chunk_size: job.chunk_size,
            camera: job.camera.clone(),
            bake_proxy: job.bake_proxy,
            submitted_at: rfc3339_utc(SystemTime::now()),
            job: sub.job.clone(),
            assemble_job: sub.assemble_job.clone(),
            assemble_command: job.assemble_command(),
            submit_commands: sub.commands.clone(),
            files: sub.files.clone(),
            chunks,
        }
    }

    /// Writes the plan atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).map_err(|e| Error::msg(format!("internal: {e}")))?;
        write_atomic(path, format!("{text}\n").as_bytes())
    }

    /// Reads a plan; None when there is none.
    pub fn read_if_any(path: &Path) -> Result<Option<FarmPlan>> {
        let text = match crate::usd_io::regular::read_regular_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(Error::msg(format!("cannot read the farm plan: {e}")).in_file(path)),
        };
        let plan: FarmPlan = serde_json::from_str(&text)
            .map_err(|e| Error::msg(format!("not a painterly farm plan: {e}")).in_file(path))?;
        if plan.format != FORMAT {
            return Err(Error::msg(format!(
                "farm plan format {:?}, this painterly reads {FORMAT:?}: submit again",
                plan.format
            ))
            .in_file(path));
        }
        Ok(Some(plan))
    }

    /// Every task id the plan records: chunk tasks, then the assembly.
    pub fn task_ids(&self) -> Vec<String> {
        self.chunks
            .iter()
            .filter_map(|c| c.task.clone())
            .chain(self.assemble_job.clone())
            .collect()
    }
}

/// The word for a chunk state on disk.
pub fn state_word(s: &ChunkState) -> &'static str {
    match s {
        ChunkState::Done => "done",
        ChunkState::Missing => "missing",
        ChunkState::Stale(_) => "stale",
    }
}

/// `t` as `YYYY-MM-DDTHH:MM:SSZ`.
pub fn rfc3339_utc(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn utc_timestamps() {
        let at = |s: u64| rfc3339_utc(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        // 2000-02-29 12:34:56 UTC (a leap day) and 2026-12-01 00:00:00 UTC,
        // from `date -u -d @951827696` and `date -u -d @1796083200`.
        assert_eq!(at(951_827_696), "2000-02-29T12:34:56Z");
        assert_eq!(at(1_796_083_200), "2026-12-01T00:00:00Z");
    }

    #[test]
    fn plan_path_matches_the_clip_plan() {
        let clips = ClipPlan::new(Path::new("/x/shot.usda"), &[1.0, 2.0, 3.0], 2).unwrap();
        assert_eq!(plan_path(&clips), plan_path_for_output(Path::new("/x/shot.usda")));
        assert_eq!(plan_path(&clips), Path::new("/x/shot.clips/farm/plan.json"));
    }

    #[test]
    fn utc_dates_of_every_day_from_1970_to_2400() {
        // Counted day by day with the Gregorian leap rule, independently of
        // the civil-from-days formula: covers 2000 (leap) and 2100, 2200,
        // 2300 (not), every month's first and last day.
        let leap = |y: u64| y.is_multiple_of(4) && (!y.is_multiple_of(100) || y.is_multiple_of(400));
        let mut days = 0u64;
        for year in 1970..=2400u64 {
            for month in 1..=12u64 {
                let len = match month {
                    2 if leap(year) => 29,
                    2 => 28,
                    4 | 6 | 9 | 11 => 30,
                    _ => 31,
                };
                for day in 1..=len {
                    let t = UNIX_EPOCH + Duration::from_secs(days * 86_400 + 3_723);
                    let want = format!("{year:04}-{month:02}-{day:02}T01:02:03Z");
                    assert_eq!(rfc3339_utc(t), want);
                    days += 1;
                }
            }
        }
    }

    #[test]
    fn an_unreadable_plan_is_an_error_and_no_plan_is_none() {
        // A folder where the plan should be cannot be read: an error, not
        // "no plan" (which would let submit go on and status say "submit").
        let e = FarmPlan::read_if_any(Path::new("/")).unwrap_err();
        assert!(e.message.starts_with("cannot read the farm plan: "), "{e}");
        assert!(FarmPlan::read_if_any(Path::new("/nonexistent/x.clips/farm/plan.json"))
            .unwrap()
            .is_none());
    }
}
