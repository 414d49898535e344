//! `painterly farm`: a chunked bake ([`crate::usd_io::clips`]) run as farm
//! jobs.
//!
//! Every scheduler gets the same work: one task per chunk that is not yet
//! done for this input (`painterly bake IN -o shot.usda --chunk N
//! --chunk-index K`), and one assembly task that depends on all of them
//! (`… --assemble`, which checks every chunk and writes the clip set). What
//! is specific to a scheduler (how to submit, how to ask about a task) is a
//! [`Scheduler`] in its own file: [`slurm`], [`openjd`]. A plan file beside
//! the chunks ([`plan`]) records what was submitted, so `farm status` can
//! answer later from the plan, the chunk stamps and the scheduler.

pub mod openjd;
pub mod plan;
pub mod slurm;
pub mod status;

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::bake::{open_for_bake, resolve_frames, BakeOptions};
use crate::character::Character;
use crate::error::{Error, Result};
use crate::frames::FrameRange;
use crate::usd_io::clips::{self, ChunkState, ClipPlan};
use plan::FarmPlan;

/// Farm commands.
#[derive(Debug, clap::Subcommand)]
pub enum FarmCommand {
    /// Submit a chunked bake: a task per chunk not yet done, then a
    /// dependent assembly task that writes the clip set.
    ///
    /// Each task is a plain `painterly bake IN -o OUTPUT --chunk N
    /// --chunk-index K` run by this painterly binary (its absolute path);
    /// the assembly task is `painterly bake … --assemble`. Chunks already on
    /// disk and stamped with this input's hash and this painterly version
    /// are skipped, so re-submitting after a failure redoes only what is
    /// missing or stale. The plan (commands, job ids per chunk) is written
    /// to `<stem>.clips/farm/plan.json`.
    ///
    /// Example: painterly farm submit fixtures/blowfish.usda -o /tmp/slurm_shot.usda --chunk 24 --scheduler slurm --partition bake
    Submit(SubmitArgs),
    /// Tell which chunks are done, running, pending, failed, missing or
    /// stale, and whether the clip set is assembled.
    ///
    /// Reads the plan written by `farm submit`, the chunk layers' stamps
    /// and, when the scheduler's commands are on PATH, the scheduler. Exit
    /// 0 when every chunk is done and the clip set is assembled, 1
    /// otherwise (or on an error).
    ///
    /// Example: painterly farm status /tmp/shot.usda --json
    Status(StatusArgs),
}

/// `farm submit` arguments.
#[derive(Debug, clap::Args)]
pub struct SubmitArgs {
    /// The painted character (.usda, .usdc or .usdz).
    pub input: PathBuf,
    /// The clip-set layer to write (.usda); chunks go to `<stem>.clips/`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Frames per chunk (and so per task).
    #[arg(long, value_name = "N", value_parser = crate::frames::positive_count)]
    pub chunk: usize,
    /// The scheduler: `slurm` submits with sbatch; `openjd` writes an Open
    /// Job Description template (run it with `openjd run`).
    #[arg(long, value_enum)]
    pub scheduler: SchedulerKind,
    /// Time codes to bake: A, A:B or A:B:STEP (default: the stage's range).
    #[arg(long, value_name = "A:B[:STEP]", allow_hyphen_values = true)]
    pub frames: Option<FrameRange>,
    /// Camera prim, as for `bake --camera`.
    #[arg(long, value_name = "PRIM")]
    pub camera: Option<String>,
    /// Also bake proxies, as for `bake --bake-proxy`.
    #[arg(long)]
    pub bake_proxy: bool,
    /// Slurm partition for every job (slurm only).
    #[arg(long, value_name = "P")]
    pub partition: Option<String>,
    /// One more argument for every sbatch call, e.g. --sbatch-arg=--mem=4G
    /// (repeatable; slurm only).
    #[arg(long, value_name = "ARG", allow_hyphen_values = true)]
    pub sbatch_arg: Vec<String>,
    /// Print a JSON summary on stdout instead of text.
    #[arg(long)]
    pub json: bool,
    /// Print nothing on success (errors still go to stderr); with --json,
    /// only the JSON, as for bake.
    #[arg(short, long)]
    pub quiet: bool,
}

/// `farm status` arguments.
#[derive(Debug, clap::Args)]
pub struct StatusArgs {
    /// The clip-set layer given to `farm submit -o`.
    pub output: PathBuf,
    /// Print the status as JSON.
    #[arg(long)]
    pub json: bool,
    /// Print nothing: the exit code alone says whether the shot is done
    /// (with --json, only the JSON).
    #[arg(short, long)]
    pub quiet: bool,
}

/// The schedulers `farm submit` knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SchedulerKind {
    /// Slurm: a job array (a task per chunk) and an afterok assembly job.
    Slurm,
    /// Open Job Description: a template with a chunk step and a dependent
    /// assembly step (what AWS Deadline Cloud runs; `openjd run` runs it locally).
    Openjd,
}

impl SchedulerKind {
    fn scheduler(self, args: Option<&SubmitArgs>) -> Box<dyn Scheduler> {
        match self {
            SchedulerKind::Slurm => Box::new(slurm::Slurm {
                partition: args.and_then(|a| a.partition.clone()),
                extra: args.map(|a| a.sbatch_arg.clone()).unwrap_or_default(),
            }),
            SchedulerKind::Openjd => Box::new(openjd::OpenJd),
        }
    }
}

/// The work of a farm bake: what every task runs, and which chunks are done.
#[derive(Debug, Clone)]
pub struct FarmJob {
    /// Absolute paths: tasks run in another directory, on another host.
    pub input: PathBuf,
    pub output: PathBuf,
    pub chunk_size: usize,
    /// `--frames` as given (tasks get the same option).
    pub frames: Option<FrameRange>,
    pub camera: Option<String>,
    pub bake_proxy: bool,
    /// The painterly binary tasks run: this one.
    pub painterly: PathBuf,
    pub input_hash: String,
    /// The resolved frames, `A:B:STEP`.
    pub frame_range: FrameRange,
    pub times: Vec<f64>,
    pub clips: ClipPlan,
    /// The state of every chunk on disk now.
    pub states: Vec<ChunkState>,
}

impl FarmJob {
    /// A task's command: `PROGRAM bake INPUT -o OUTPUT --chunk N [options]
    /// LAST…`; the words for the program and paths are given so a template
    /// can put its own parameters there.
    pub fn command(&self, program: &str, input: &str, output: &str, last: &[&str]) -> Vec<String> {
        let mut a: Vec<String> = [program, "bake", input, "-o", output, "--chunk"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        a.push(self.chunk_size.to_string());
        if let Some(f) = self.frames {
            a.push(format!("--frames={}:{}:{}", f.start, f.end, f.step));
        }
        if let Some(c) = &self.camera {
            a.push(format!("--camera={c}"));
        }
        if self.bake_proxy {
            a.push("--bake-proxy".into());
        }
        a.extend(last.iter().map(|s| s.to_string()));
        a
    }

    fn own_command(&self, last: &[&str]) -> Vec<String> {
        self.command(
            &self.painterly.to_string_lossy(),
            &self.input.to_string_lossy(),
            &self.output.to_string_lossy(),
            last,
        )
    }

    /// The command of a chunk task (program first).
    pub fn chunk_command(&self, chunk: usize) -> Vec<String> {
        self.own_command(&["--chunk-index", &chunk.to_string()])
    }

    /// A chunk task's command without the chunk index, which a job script
    /// appends.
    pub fn chunk_command_head(&self) -> Vec<String> {
        self.own_command(&["--chunk-index"])
    }

    /// The command of the assembly task (program first).
    pub fn assemble_command(&self) -> Vec<String> {
        self.own_command(&["--assemble"])
    }

    /// Indices of the chunks a submission must bake: missing or stale.
    pub fn todo(&self) -> Vec<usize> {
        (0..self.states.len())
            .filter(|&k| self.states[k] != ChunkState::Done)
            .collect()
    }

    /// Where the plan, scripts and logs go: `<stem>.clips/farm/`.
    pub fn farm_dir(&self) -> PathBuf {
        farm_dir(&self.clips)
    }

    /// Checks the input and output as `bake` would, resolves the frames
    /// and chunks, and reads which chunks are already done; also returns
    /// the opened character (its binding goes to the binding cache).
    pub fn prepare(args: &SubmitArgs) -> Result<(FarmJob, Character)> {
        let opts = BakeOptions {
            frames: args.frames,
            bake_proxy: args.bake_proxy,
            camera: args.camera.clone(),
            chunk: Some(args.chunk),
            chunk_index: None,
            assemble: false,
            cancel: None,
        };
        let character = open_for_bake(&args.input, &args.output, &opts)?;
        let reader = &character.reader;
        let times = resolve_frames(reader, args.frames).map_err(|e| e.in_file(&args.input))?;
        // One frame evaluated here refuses what would fail every task (a
        // review, 2026-12-07: an axis with no source was submitted, and
        // every task failed); a problem of some frames only still shows in
        // their tasks.
        if let Some(&first) = times.first() {
            crate::bake::evaluate_one_frame(&character, first, args.bake_proxy).map_err(|e| e.in_file(&args.input))?;
        }
        let frame_range = resolved_range(&times, args.frames);
        let input_hash = clips::input_hash(reader)?;
        let output = absolute(&args.output)?;
        let clips = ClipPlan::new(&output, &times, args.chunk)?;
        let options = crate::bake::options_text(args.bake_proxy, args.camera.as_deref());
        let states = clips::chunk_states(&clips, &input_hash, options.as_deref(), &times)?;
        let painterly = std::env::current_exe()
            .map_err(|e| Error::msg(format!("cannot find the painterly binary's own path: {e}")))?;
        let job = FarmJob {
            input: absolute(&args.input)?,
            output,
            chunk_size: args.chunk,
            frames: args.frames,
            camera: args.camera.clone(),
            bake_proxy: args.bake_proxy,
            painterly,
            input_hash,
            frame_range,
            times,
            clips,
            states,
        };
        Ok((job, character))
    }
}

/// The frame range whose `times()` are `times`: the option, or the stage's
/// whole range at step 1.
fn resolved_range(times: &[f64], given: Option<FrameRange>) -> FrameRange {
    given.unwrap_or(FrameRange {
        start: times.first().copied().unwrap_or(0.0),
        end: times.last().copied().unwrap_or(0.0),
        step: 1.0,
    })
}

/// `<stem>.clips/farm/` of a clip plan.
pub fn farm_dir(clips: &ClipPlan) -> PathBuf {
    clips.dir.join("farm")
}

/// An absolute path (the file need not exist; its folder must).
pub fn absolute(path: &Path) -> Result<PathBuf> {
    if let Ok(p) = path.canonicalize() {
        return Ok(p);
    }
    let name = path
        .file_name()
        .ok_or_else(|| Error::msg("path has no file name").in_file(path))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let dir = dir
        .canonicalize()
        .map_err(|e| Error::msg(format!("cannot resolve the folder: {e}")).in_file(path))?;
    Ok(dir.join(name))
}

/// What a scheduler did with a submission.
#[derive(Debug, Clone, Default)]
pub struct Submission {
    /// The scheduler's id of the chunk tasks as a whole (Slurm: the array job).
    pub job: Option<String>,
    /// Per submitted chunk (index), the scheduler's id of its task.
    pub tasks: Vec<(usize, String)>,
    /// The assembly task's id.
    pub assemble_job: Option<String>,
    /// Files written (job scripts, templates).
    pub files: Vec<PathBuf>,
    /// The submission commands run, exactly.
    pub commands: Vec<Vec<String>>,
    /// What the user runs next, when the scheduler is not asked directly.
    pub next: Option<String>,
}

/// What a scheduler says about a task.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskState {
    Pending,
    Running,
    /// Ended successfully.
    Completed,
    /// Ended otherwise: failed, cancelled, timed out, out of memory, ….
    Failed,
}

/// A task as the scheduler reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskInfo {
    pub state: TaskState,
    /// The scheduler's own word for the state (e.g. Slurm's `CANCELLED`).
    pub raw: String,
    /// Why it waits or ended, when the scheduler says.
    pub reason: Option<String>,
}

/// One scheduler: how to submit the chunk tasks and the assembly, and how
/// to ask about them afterwards. Adding OpenCue or Tractor is one more
/// implementation.
pub trait Scheduler {
    /// Submits a task for every chunk in `todo` and an assembly task that
    /// runs after all of them succeed (or at once when `todo` is empty).
    fn submit(&self, job: &FarmJob, todo: &[usize]) -> Result<Submission>;

    /// What the scheduler knows of these task ids; None when it cannot be
    /// asked (not installed here, or it keeps no live state). Ids it no
    /// longer knows are absent from the map.
    fn query(&self, ids: &[String]) -> Option<HashMap<String, TaskInfo>>;

    /// How to cancel a task, for messages.
    fn cancel_hint(&self, id: &str) -> String;
}

/// A summary of a submission, printed by `farm submit` (`--json` prints it as is).
#[derive(Debug, serde::Serialize)]
pub struct SubmitSummary {
    pub scheduler: SchedulerKind,
    pub input: PathBuf,
    pub output: PathBuf,
    pub plan: PathBuf,
    pub chunk_size: usize,
    pub chunks: usize,
    pub submitted: Vec<usize>,
    pub skipped: Vec<usize>,
    pub job: Option<String>,
    pub tasks: Vec<TaskRef>,
    pub assemble_job: Option<String>,
    pub files: Vec<PathBuf>,
    pub next: Option<String>,
}

/// A chunk and its task id.
#[derive(Debug, serde::Serialize)]
pub struct TaskRef {
    pub chunk: usize,
    pub task: String,
}

/// `farm submit`.
pub fn submit(args: &SubmitArgs) -> Result<SubmitSummary> {
    let scheduler = args.scheduler.scheduler(Some(args));
    if let SchedulerKind::Slurm = args.scheduler {
        slurm::check_installed()?;
    }
    let (job, character) = FarmJob::prepare(args)?;
    let plan_path = plan::plan_path(&job.clips);
    std::fs::create_dir_all(job.farm_dir().join("logs"))
        .map_err(|e| Error::msg(format!("cannot create the farm folder: {e}")).in_file(&job.farm_dir()))?;
    // From reading the previous plan to writing this one: two submissions of
    // one shot at once both passed the live-task check, shared the job
    // scripts, and the later plan hid the other's tasks.
    let _submitting = hold_submit_lock(&job.farm_dir())?;
    if let Some(previous) = FarmPlan::read_if_any(&plan_path)? {
        refuse_live_tasks(&previous, &plan_path)?;
    }
    let todo = job.todo();
    if !todo.is_empty() {
        // Bound once here, for every task and the assembly.
        crate::bake::leave_binding_cache(&character, &job.output);
    }
    drop(character);
    let sub = scheduler.submit(&job, &todo)?;
    let plan = FarmPlan::new(args.scheduler, &job, &sub);
    plan.write(&plan_path).map_err(|e| {
        Error::msg(format!(
            "{} (the jobs were submitted: chunk tasks {}, assembly {})",
            e.message,
            sub.job.as_deref().unwrap_or("none"),
            sub.assemble_job.as_deref().unwrap_or("none")
        ))
        .in_file(&plan_path)
    })?;
    Ok(SubmitSummary {
        scheduler: args.scheduler,
        input: job.input.clone(),
        output: job.output.clone(),
        plan: plan_path,
        chunk_size: job.chunk_size,
        chunks: job.clips.chunks.len(),
        // `todo` is sorted: a search, not a scan per chunk.
        skipped: (0..job.clips.chunks.len())
            .filter(|k| todo.binary_search(k).is_err())
            .collect(),
        submitted: todo,
        job: sub.job,
        tasks: sub
            .tasks
            .into_iter()
            .map(|(chunk, task)| TaskRef { chunk, task })
            .collect(),
        assemble_job: sub.assemble_job,
        files: sub.files,
        next: sub.next,
    })
}

/// How long a submission waits for another one of the same shot.
const SUBMIT_LOCK_WAIT: std::time::Duration = std::time::Duration::from_secs(60);

/// The lock on `farm/submit.lock` that one submission of a shot holds.
fn hold_submit_lock(farm_dir: &Path) -> Result<std::fs::File> {
    let path = farm_dir.join("submit.lock");
    match crate::usd_io::atomic::hold_lock(&path, SUBMIT_LOCK_WAIT) {
        Ok(Some(f)) => Ok(f),
        Ok(None) => Err(Error::msg(format!(
            "another `painterly farm submit` of this shot has held this lock for over {} s; wait for it to end, \
             then see `painterly farm status`",
            SUBMIT_LOCK_WAIT.as_secs()
        ))
        .in_file(&path)),
        Err(e) => Err(Error::msg(format!("cannot lock: {e}")).in_file(&path)),
    }
}

/// Refuses to submit while tasks of the previous submission still wait or
/// run: two tasks writing one chunk waste a node and race on the rename.
fn refuse_live_tasks(previous: &FarmPlan, plan_path: &Path) -> Result<()> {
    let scheduler = previous.scheduler.scheduler(None);
    let ids = previous.task_ids();
    let Some(known) = scheduler.query(&ids) else {
        return Ok(());
    };
    let live: Vec<String> = ids
        .iter()
        .filter(|id| {
            known
                .get(*id)
                .is_some_and(|t| matches!(t.state, TaskState::Pending | TaskState::Running))
        })
        .cloned()
        .collect();
    if live.is_empty() {
        return Ok(());
    }
    let jobs: Vec<&str> = [previous.job.as_deref(), previous.assemble_job.as_deref()]
        .into_iter()
        .flatten()
        .collect();
    let hints: Vec<String> = jobs.iter().map(|j| scheduler.cancel_hint(j)).collect();
    Err(Error::msg(format!(
        "tasks of the previous submission still wait or run ({}): wait for them (painterly farm status) or cancel them ({}) before submitting again",
        live.join(", "),
        hints.join("; ")
    ))
    .in_file(plan_path))
}

impl SubmitSummary {
    /// The human-readable summary.
    pub fn to_text(&self) -> String {
        // " (0, 2)" after a count, nothing after a zero.
        let list = |v: &[usize]| {
            if v.is_empty() {
                String::new()
            } else {
                format!(" ({})", v.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", "))
            }
        };
        let mut s = format!(
            "{}: {} chunks of {} frames: {} to bake{}, {} already done{}\n",
            self.output.display(),
            self.chunks,
            self.chunk_size,
            self.submitted.len(),
            list(&self.submitted),
            self.skipped.len(),
            list(&self.skipped),
        );
        match (self.scheduler, &self.job, &self.assemble_job) {
            (SchedulerKind::Slurm, job, Some(asm)) => {
                if let Some(job) = job {
                    s += &format!("slurm: chunk tasks job {job}, assembly job {asm} (after {job} succeeds)\n");
                } else {
                    s += &format!("slurm: assembly job {asm}\n");
                }
            }
            _ => {
                for f in &self.files {
                    s += &format!("wrote {}\n", f.display());
                }
            }
        }
        if let Some(next) = &self.next {
            s += &format!("run it: {next}\n");
        }
        s += &format!("status: painterly farm status {}\n", self.output.display());
        s
    }
}

/// Runs `farm`; returns the exit code.
pub fn run(cmd: FarmCommand) -> i32 {
    match cmd {
        FarmCommand::Submit(args) => {
            if args.scheduler != SchedulerKind::Slurm && (args.partition.is_some() || !args.sbatch_arg.is_empty()) {
                eprintln!("error: --partition and --sbatch-arg are for --scheduler slurm");
                return 2;
            }
            match submit(&args) {
                Ok(s) => {
                    if args.json {
                        println!("{}", serde_json::to_string_pretty(&s).unwrap_or_default());
                    } else if !args.quiet {
                        print!("{}", s.to_text());
                    }
                    0
                }
                Err(e) => report(&e),
            }
        }
        FarmCommand::Status(args) => match status::status(&args.output) {
            Ok(st) => {
                if args.json {
                    println!("{}", serde_json::to_string_pretty(&st).unwrap_or_default());
                } else if !args.quiet {
                    print!("{}", st.to_text());
                }
                if st.complete {
                    0
                } else {
                    1
                }
            }
            Err(e) => report(&e),
        },
    }
}

fn report(e: &Error) -> i32 {
    eprintln!("error: {e}");
    e.exit_code()
}

/// The full path of `program` on PATH, if any.
pub fn find_on_path(program: &str) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(program)).find(|p| {
        p.metadata()
            .is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
    })
}

/// A finished tool run.
#[derive(Debug)]
pub struct ToolOutput {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

/// Runs a scheduler tool (`argv[0]` from PATH) with a time limit, so a
/// scheduler that does not answer cannot hang painterly.
pub fn run_tool(argv: &[String], limit: Duration) -> Result<ToolOutput> {
    let (program, args) = argv
        .split_first()
        .ok_or_else(|| Error::msg("internal: empty command"))?;
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| Error::msg(format!("cannot run {program}: {e}")))?;
    // Drain both pipes on threads so a chatty tool cannot block on a full pipe.
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_string(&mut s);
            }
            s
        })
    };
    let out = drain(child.stdout.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let err = drain(child.stderr.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let started = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break s,
            Ok(None) if started.elapsed() > limit => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::msg(format!(
                    "{program} did not answer within {} s: is the scheduler reachable?",
                    limit.as_secs()
                )));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => return Err(Error::msg(format!("cannot wait for {program}: {e}"))),
        }
    };
    Ok(ToolOutput {
        code: status.code(),
        stdout: out.join().unwrap_or_default(),
        stderr: err.join().unwrap_or_default(),
    })
}

/// `argv` as one shell-quoted line, for scripts and messages.
pub fn shell_line(argv: &[String]) -> String {
    argv.iter().map(|a| shell_quote(a)).collect::<Vec<_>>().join(" ")
}

/// One word quoted for POSIX shells (left bare when it is plainly safe).
pub fn shell_quote(s: &str) -> String {
    let safe = !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
    if safe {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_quoting_round_trips_through_sh() {
        let words = [
            "plain",
            "with space",
            "it's",
            "$HOME",
            "a\"b",
            "",
            "--frames=1:48:0.5",
            "*",
        ];
        let argv: Vec<String> = words.iter().map(|s| s.to_string()).collect();
        let line = format!("printf '%s\\n' {}", shell_line(&argv));
        let out = Command::new("sh").arg("-c").arg(&line).output().unwrap();
        let got: Vec<&str> = std::str::from_utf8(&out.stdout).unwrap().lines().collect();
        assert_eq!(got, words);
    }

    #[test]
    fn run_tool_times_out_and_reports_exit_codes() {
        let sleep = ["sleep".to_string(), "5".to_string()];
        let e = run_tool(&sleep, Duration::from_millis(200)).unwrap_err();
        assert!(e.message.contains("did not answer within"), "{e}");
        let fail = [
            "sh".to_string(),
            "-c".to_string(),
            "echo out; echo err >&2; exit 3".to_string(),
        ];
        let o = run_tool(&fail, Duration::from_secs(5)).unwrap();
        assert_eq!(
            (o.code, o.stdout.as_str(), o.stderr.as_str()),
            (Some(3), "out\n", "err\n")
        );
    }

    #[test]
    fn absolute_joins_a_new_file_to_its_folder_or_the_current_one() {
        // A file not yet written: its folder's canonical path, then its name.
        let scratch = crate::test_dir::ScratchDir::new("farm-absolute");
        let folder = scratch.canonicalize().unwrap();
        assert_eq!(absolute(&scratch.join("new.usda")).unwrap(), folder.join("new.usda"));
        // An existing file resolves through its own canonical path.
        std::fs::write(folder.join("old.usda"), "#usda 1.0\n").unwrap();
        assert_eq!(
            absolute(&scratch.join(".").join("old.usda")).unwrap(),
            folder.join("old.usda")
        );
        // A bare name (its parent is the empty path) is in the current folder.
        let bare = Path::new("painterly-farm-absolute-no-such-file.usda");
        assert!(!bare.exists());
        let here = std::env::current_dir().unwrap().canonicalize().unwrap();
        assert_eq!(absolute(bare).unwrap(), here.join(bare));
        // A folder that does not exist cannot be resolved.
        let e = absolute(&scratch.join("no").join("shot.usda")).unwrap_err();
        assert!(e.message.starts_with("cannot resolve the folder: "), "{e}");
    }

    fn summary(scheduler: SchedulerKind) -> SubmitSummary {
        SubmitSummary {
            scheduler,
            input: "/x/in.usda".into(),
            output: "/x/shot.usda".into(),
            plan: "/x/shot.clips/farm/plan.json".into(),
            chunk_size: 12,
            chunks: 4,
            submitted: vec![1, 3],
            skipped: vec![0, 2],
            job: None,
            tasks: Vec::new(),
            assemble_job: None,
            files: Vec::new(),
            next: None,
        }
    }

    #[test]
    fn the_submit_text_says_what_was_submitted_for_slurm() {
        let mut s = summary(SchedulerKind::Slurm);
        s.job = Some("4242".into());
        s.assemble_job = Some("4243".into());
        s.files = vec![
            "/x/shot.clips/farm/bake.sh".into(),
            "/x/shot.clips/farm/assemble.sh".into(),
        ];
        assert_eq!(
            s.to_text(),
            "/x/shot.usda: 4 chunks of 12 frames: 2 to bake (1, 3), 2 already done (0, 2)\n\
             slurm: chunk tasks job 4242, assembly job 4243 (after 4242 succeeds)\n\
             status: painterly farm status /x/shot.usda\n"
        );
        // Every chunk done: only the assembly job was submitted.
        s.job = None;
        s.submitted = vec![];
        s.skipped = vec![0, 1, 2, 3];
        s.files = vec!["/x/shot.clips/farm/assemble.sh".into()];
        assert_eq!(
            s.to_text(),
            "/x/shot.usda: 4 chunks of 12 frames: 0 to bake, 4 already done (0, 1, 2, 3)\n\
             slurm: assembly job 4243\n\
             status: painterly farm status /x/shot.usda\n"
        );
    }

    #[test]
    fn the_submit_text_lists_the_openjd_files_and_the_command_to_run() {
        let mut s = summary(SchedulerKind::Openjd);
        s.submitted = vec![0, 1, 2, 3];
        s.skipped = vec![];
        s.assemble_job = Some("Assemble".into());
        s.files = vec!["/x/t.json".into(), "/x/p.json".into()];
        s.next = Some("openjd run /x/t.json -p file:///x/p.json".into());
        assert_eq!(
            s.to_text(),
            "/x/shot.usda: 4 chunks of 12 frames: 4 to bake (0, 1, 2, 3), 0 already done\n\
             wrote /x/t.json\n\
             wrote /x/p.json\n\
             run it: openjd run /x/t.json -p file:///x/p.json\n\
             status: painterly farm status /x/shot.usda\n"
        );
    }
}
