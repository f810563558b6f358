//! Design studies on the explorer's Studies page (`docs/explore.md`, `docs/studies.md`).
//!
//! Two sources, listed side by side:
//! - the pipeline's studies: the units of its study stages (every stage running the `study`
//!   binary, whatever its name), their state and files read as `pipeline status` and
//!   `pipeline show` read them (nothing here runs a stage);
//! - studies started from the sweep view: one declaration of a study stage's matrix (the
//!   sweep's one or two parameters uniform over their intervals, every other parameter fixed
//!   at the design's value, each design under its own excitation), run in the background by
//!   the stage's own library ([`pino_study::run`]) on the model being explored.
//!
//! A started study writes into `<dir>/<name>.partial/` and is renamed to `<dir>/<name>/` once
//! every file is written, so a run cut short is never listed as finished. Beside the study's
//! files it keeps its declaration ([`DECLARATION_FILE`], ready to paste under the pipeline
//! file's `study:` matrix) and the record the page lists it by ([`RECORD_FILE`]), so a later
//! session of the explorer lists it again. One started study runs at a time, beside the
//! interactive requests, never in front of them: on its own thread pool (`--study-threads`),
//! so a prediction or a solve never queues behind its work, at a lower CPU priority, so they
//! take the cores they need whenever they ask. Its progress (designs answered by the surrogate and the solver) is
//! listed while it runs, and it can be cancelled (it stops at its next slice of designs). The
//! request caps ([`crate::request::STUDY_MAX_MONTE_CARLO`], ...) keep it to a minute or two;
//! larger studies belong in the pipeline file.

use crate::request::{ApiError, Excitation, StudyRequest};
use crate::session::Explorer;
use orchestrator::spec::Pipeline;
use orchestrator::status::{show, unit_states};
use pino_study::output::{headline_table, SUMMARY_MD_FILE};
use pino_study::{Progress, StudyParams};
use serde::{Deserialize, Serialize};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// The stage binary of design studies: the units of every stage running it are the
/// pipeline's studies.
pub const STUDY_COMMAND: &str = "study";

/// The parameter of a study stage holding one study's declaration (its matrix key).
pub const STUDY_PARAM: &str = "study";

/// A started study's declaration, as YAML.
pub const DECLARATION_FILE: &str = "study.yaml";

/// A started study's record: its declaration, model, one-line summary and wall time.
pub const RECORD_FILE: &str = "explore-study.json";

/// Suffix of a started study's directory while it runs.
const PARTIAL_SUFFIX: &str = ".partial";

/// The most bytes of a study's Markdown report the page is sent.
const SUMMARY_MD_MAX_BYTES: u64 = 512 * 1024;

/// Where a study comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// A unit of one of the pipeline's study stages.
    Pipeline,
    /// Started from the explorer's sweep view.
    Explorer,
}

impl Source {
    /// The name used in URLs and answers.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Pipeline => "pipeline",
            Self::Explorer => "explorer",
        }
    }

    /// The source named `name` in a URL.
    pub fn parse(name: &str) -> Option<Self> {
        [Self::Pipeline, Self::Explorer]
            .into_iter()
            .find(|s| s.as_str() == name)
    }
}

/// A CSV table: its file name and rows, the header first.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TableView {
    /// The file.
    pub file: String,
    /// Its rows, the header first.
    pub rows: Vec<Vec<String>>,
}

/// A study as the page shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyView {
    /// Where it comes from.
    pub source: Source,
    /// Its declared name.
    pub name: String,
    /// `monte_carlo`, `sensitivity` or `optimise`.
    pub kind: String,
    /// The unit's state (`fresh`, `stale`, `never run`, `running`, ...) or a started study's
    /// (`running`, `finished`, `failed`, `cancelled`).
    pub state: String,
    /// Why (stale), the progress, the one-line summary or the error.
    pub detail: String,
    /// A running started study's designs answered so far.
    pub progress: Option<StudyProgress>,
    /// The declaration, as YAML.
    pub declaration: String,
    /// The Markdown report, when written.
    pub summary_md: Option<String>,
    /// The table a reader opens first ([`headline_table`]).
    pub table: Option<TableView>,
    /// The plots (PNG file names).
    pub plots: Vec<String>,
    /// Every file of the study's output.
    pub files: Vec<String>,
    /// The directory of its files.
    #[serde(skip)]
    pub dir: Option<PathBuf>,
}

/// How far a running started study is: designs answered by the surrogate and by the solver,
/// each of those asked for so far, and whether it was asked to stop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyProgress {
    /// Designs answered, surrogate and solver together.
    pub done: usize,
    /// Designs asked for so far.
    pub total: usize,
    /// The same in words.
    pub message: String,
    /// Whether a cancel was asked for (it stops at its next slice of designs).
    pub cancelling: bool,
}

impl StudyProgress {
    fn of(p: &Progress) -> Self {
        let (sd, st) = p.surrogate();
        let (vd, vt) = p.solver();
        let mut message = if st == 0 {
            "opening the model".to_owned()
        } else {
            format!("{sd} of {st} designs through the surrogate")
        };
        if vt > 0 {
            message.push_str(&format!(", {vd} of {vt} through the solver"));
        }
        Self {
            done: sd + vd,
            total: st + vt,
            message,
            cancelling: p.cancelled(),
        }
    }
}

/// The names of `dir`'s entries that are directories (`dirs`) or plain files, sorted.
fn entry_names(dir: &Path, dirs: bool) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| {
            e.file_type()
                .is_ok_and(|t| if dirs { t.is_dir() } else { t.is_file() })
        })
        .filter_map(|e| e.file_name().into_string().ok())
        .collect();
    names.sort();
    names
}

/// The file names in `dir` (plain files, hidden ones left out, sorted).
fn file_names(dir: &Path) -> Vec<String> {
    let mut names = entry_names(dir, false);
    names.retain(|n| !n.starts_with('.'));
    names
}

/// Fills `view`'s report, table, plots and file list from the study's output directory.
fn with_outputs(mut view: StudyView, dir: &Path) -> StudyView {
    let files = file_names(dir);
    let has = |name: &str| files.iter().any(|f| f == name);
    view.summary_md = has(SUMMARY_MD_FILE)
        .then(|| {
            use std::io::Read;
            let mut text = String::new();
            std::fs::File::open(dir.join(SUMMARY_MD_FILE))
                .and_then(|f| f.take(SUMMARY_MD_MAX_BYTES).read_to_string(&mut text))
                .ok()
                .map(|_| text)
        })
        .flatten();
    view.table = headline_table(&view.kind).filter(|f| has(f)).and_then(|f| {
        crate::tables::read_csv(&dir.join(f))
            .ok()
            .map(|rows| TableView {
                file: f.to_owned(),
                rows,
            })
    });
    view.plots = files
        .iter()
        .filter(|f| f.ends_with(".png"))
        .cloned()
        .collect();
    view.files = files;
    view.dir = Some(dir.to_owned());
    view
}

fn yaml_of(declaration: &Value) -> String {
    serde_yaml::to_string(declaration).unwrap_or_default()
}

fn field_str(v: &Value, key: &str) -> String {
    v.get(key).and_then(Value::as_str).unwrap_or("").to_owned()
}

/// The pipeline's studies: every expansion of its study stages ([`STUDY_COMMAND`]), in the
/// pipeline's order, with its state and the files of its current output when it has one.
/// Empty when the pipeline has no such stage.
pub fn pipeline_studies(p: &Pipeline) -> Result<Vec<StudyView>, String> {
    let study_stages: Vec<usize> = p.stages_running(STUDY_COMMAND).map(|(i, _)| i).collect();
    if study_stages.is_empty() {
        return Ok(Vec::new());
    }
    let mut views: Vec<StudyView> = Vec::new();
    let mut seen = Vec::new();
    for u in unit_states(p).map_err(|e| e.to_string())? {
        if !study_stages.contains(&u.stage) || seen.contains(&(u.stage, u.expansion)) {
            continue;
        }
        seen.push((u.stage, u.expansion));
        let e = &p.stages[u.stage].expansions[u.expansion];
        let declaration = e.params.get(STUDY_PARAM).cloned().unwrap_or(Value::Null);
        let view = StudyView {
            source: Source::Pipeline,
            name: field_str(&declaration, "name"),
            kind: field_str(&declaration, "kind"),
            state: u.state.to_owned(),
            detail: u.detail,
            progress: None,
            declaration: yaml_of(&declaration),
            summary_md: None,
            table: None,
            plots: Vec::new(),
            files: Vec::new(),
            dir: None,
        };
        views.push(match output_dir(p, &e.name) {
            Some(dir) => with_outputs(view, &dir),
            None => view,
        });
    }
    Ok(views)
}

/// The directory of the current output of the pipeline's study expansion `expansion`.
fn output_dir(p: &Pipeline, expansion: &str) -> Option<PathBuf> {
    let text = show(p, expansion).ok()?;
    Path::new(text.lines().next()?)
        .parent()
        .map(Path::to_path_buf)
}

/// The directory of the current output of the pipeline's study named `name`, found by its
/// declaration alone (no unit states read, no report).
fn pipeline_study_dir(p: &Pipeline, name: &str) -> Option<PathBuf> {
    let e = p
        .stages_running(STUDY_COMMAND)
        .flat_map(|(_, s)| &s.expansions)
        .find(|e| {
            e.params
                .get(STUDY_PARAM)
                .is_some_and(|d| field_str(d, "name") == name)
        })?;
    output_dir(p, &e.name)
}

/// What a finished started study keeps beside its files ([`RECORD_FILE`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The declaration (one value of the `study` stage's matrix).
    pub declaration: Value,
    /// The identity of the model that answered.
    pub model: String,
    /// The stage's one-line summary.
    pub summary: String,
    /// Wall time of the whole study (s).
    pub seconds: f64,
}

/// Where a started study stands.
#[derive(Debug, Clone)]
enum JobState {
    Running {
        started: Instant,
        progress: Arc<Progress>,
    },
    Finished {
        summary: String,
    },
    Failed {
        error: String,
    },
    Cancelled {
        after_s: f64,
    },
}

/// A started study.
#[derive(Debug, Clone)]
struct Job {
    name: String,
    declaration: Value,
    state: JobState,
}

/// The studies started from the explorer: their directory, their jobs and the threads each
/// runs on.
pub struct Studies {
    dir: PathBuf,
    jobs: Mutex<Vec<Job>>,
    running: AtomicBool,
    threads: usize,
}

/// Clears the running flag when the study's thread ends, however it ends.
struct RunningFlag(Arc<Studies>);

impl Drop for RunningFlag {
    fn drop(&mut self) {
        self.0.running.store(false, Ordering::SeqCst);
    }
}

/// An accepted start: the study's name and declaration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Started {
    /// The study's name (its directory under the studies directory).
    pub name: String,
    /// The declaration, as YAML.
    pub declaration: String,
}

/// How many nice steps below the interactive work a started study runs (at most 19): on a
/// core both want, the kernel gives the interactive request nine tenths of the time (CFS
/// weights 1024 to 110) and wakes it first (BENCHMARKS.md, "Explorer": 5 steps left a
/// slower p99).
const STUDY_NICENESS: i32 = 10;

/// The threads of a started study: `threads` of them, made by the calling thread (whose
/// priority they inherit), so the interactive requests, on the default pool and the blocking
/// pool, never queue behind the study's work.
fn study_pool(threads: usize) -> Result<rayon::ThreadPool, String> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .thread_name(|k| format!("study-{k}"))
        .build()
        .map_err(|e| format!("starting the study's threads: {e}"))
}

/// Lowers the calling thread's CPU priority by [`STUDY_NICENESS`] (a thread's own on Linux;
/// the threads it then makes inherit it).
fn lower_priority() {
    #[cfg(unix)]
    // SAFETY: nice only reads its integer argument; a failure leaves the priority as it was.
    unsafe {
        libc::nice(STUDY_NICENESS);
    }
}

impl Studies {
    /// The started studies kept in `dir` (created on the first start), those of earlier
    /// sessions listed as finished; each study runs on `threads` threads.
    pub fn open(dir: PathBuf, threads: usize) -> Self {
        let mut jobs = Vec::new();
        for name in file_dirs(&dir) {
            let Ok(text) = std::fs::read_to_string(dir.join(&name).join(RECORD_FILE)) else {
                continue;
            };
            if let Ok(r) = serde_json::from_str::<Record>(&text) {
                jobs.push(Job {
                    name,
                    declaration: r.declaration,
                    state: JobState::Finished { summary: r.summary },
                });
            }
        }
        Self {
            dir,
            jobs: Mutex::new(jobs),
            running: AtomicBool::new(false),
            threads: threads.max(1),
        }
    }

    /// The directory of the started studies.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Whether a started study is running.
    pub fn is_running(&self) -> bool {
        self.running.load(Ordering::SeqCst)
    }

    fn jobs(&self) -> std::sync::MutexGuard<'_, Vec<Job>> {
        self.jobs.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The started studies, the latest first; a finished one with its files, a running one
    /// with its progress.
    pub fn list(&self) -> Vec<StudyView> {
        let jobs = self.jobs().clone();
        jobs.into_iter()
            .rev()
            .map(|j| {
                let mut progress = None;
                let (state, detail) = match &j.state {
                    JobState::Running {
                        started,
                        progress: p,
                    } => {
                        let shown = StudyProgress::of(p);
                        let detail = format!(
                            "running for {:.0} s: {}{}",
                            started.elapsed().as_secs_f64(),
                            shown.message,
                            if shown.cancelling { "; cancelling" } else { "" }
                        );
                        progress = Some(shown);
                        ("running", detail)
                    }
                    JobState::Finished { summary } => ("finished", summary.clone()),
                    JobState::Failed { error } => ("failed", error.clone()),
                    JobState::Cancelled { after_s } => (
                        "cancelled",
                        format!("cancelled after {after_s:.0} s: nothing was kept"),
                    ),
                };
                let view = StudyView {
                    source: Source::Explorer,
                    kind: field_str(&j.declaration, "kind"),
                    state: state.to_owned(),
                    detail,
                    progress,
                    declaration: yaml_of(&j.declaration),
                    summary_md: None,
                    table: None,
                    plots: Vec::new(),
                    files: Vec::new(),
                    dir: None,
                    name: j.name.clone(),
                };
                if matches!(j.state, JobState::Finished { .. }) {
                    with_outputs(view, &self.dir.join(&j.name))
                } else {
                    view
                }
            })
            .collect()
    }

    /// Asks the running started study `name` to stop: 404 for no such study, 409 for one
    /// that is not running.
    pub fn cancel(&self, name: &str) -> Result<(), ApiError> {
        let jobs = self.jobs();
        let job = jobs
            .iter()
            .find(|j| j.name == name)
            .ok_or_else(|| ApiError {
                status: 404,
                error: format!("no study `{name}` was started here"),
                field: Some("name".into()),
                allowed: Some("the name of a running study of the Studies page".into()),
                retry_after_s: None,
            })?;
        match &job.state {
            JobState::Running { progress, .. } => {
                progress.cancel();
                Ok(())
            }
            _ => Err(ApiError {
                status: 409,
                error: format!("the study `{name}` is not running"),
                field: Some("name".into()),
                allowed: Some("the name of a running study".into()),
                retry_after_s: None,
            }),
        }
    }

    /// Starts the study of `req` on the model of `ex` in the background; refused (429) while
    /// another runs, (400) when the declaration it makes is not a valid study of the model or
    /// a design at a corner of its intervals is one the model refuses (a speed that leaves the
    /// track: the interval's end named, as a sweep names it).
    pub fn start(
        self: &Arc<Self>,
        ex: Arc<Explorer>,
        req: &StudyRequest,
    ) -> Result<Started, ApiError> {
        let names = ex.rules().names.clone();
        let stem = std::iter::once(req.kind.as_str().to_owned())
            .chain(req.varied.iter().map(|&(k, _, _)| names[k].clone()))
            .collect::<Vec<_>>()
            .join("-");
        let params = study_params(&ex, &declaration(&ex, req, &stem), req.coverage)
            .map_err(ApiError::internal)?;
        validate(&ex, req, &params)?;
        if self.running.swap(true, Ordering::SeqCst) {
            return Err(ApiError {
                status: 429,
                error:
                    "a study started here is still running: wait for it (the Studies page shows it)"
                        .into(),
                field: None,
                allowed: None,
                retry_after_s: Some(5),
            });
        }
        let flag = RunningFlag(self.clone());
        let (name, partial) = self.claim(&stem).map_err(ApiError::internal)?;
        let decl = declaration(&ex, req, &name);
        let started = Started {
            name: name.clone(),
            declaration: yaml_of(&decl),
        };
        let progress = Arc::new(Progress::default());
        self.jobs().push(Job {
            name: name.clone(),
            declaration: decl.clone(),
            state: JobState::Running {
                started: Instant::now(),
                progress: progress.clone(),
            },
        });
        let run = Run {
            flag,
            studies: self.clone(),
            ex,
            name,
            decl,
            coverage: req.coverage,
            partial,
            progress,
        };
        std::thread::Builder::new()
            .name(format!("study {}", run.name))
            .spawn(move || run.run())
            .map_err(|e| {
                let error = format!("starting the study's thread: {e}");
                self.set_state(
                    &started.name,
                    JobState::Failed {
                        error: error.clone(),
                    },
                );
                let _ = std::fs::remove_dir_all(
                    self.dir.join(format!("{}{PARTIAL_SUFFIX}", started.name)),
                );
                ApiError::internal(error)
            })?;
        Ok(started)
    }

    fn set_state(&self, name: &str, state: JobState) {
        if let Some(j) = self.jobs().iter_mut().rev().find(|j| j.name == name) {
            j.state = state;
        }
    }

    /// A free name `<stem>-<k>` and its partial directory, claimed by creating it (so two
    /// explorers sharing the directory never write into one). A name this session listed
    /// (a failed or cancelled study, whose directory is gone) is not given again.
    fn claim(&self, stem: &str) -> Result<(String, PathBuf), String> {
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| format!("creating {}: {e}", self.dir.display()))?;
        for k in 1..100_000 {
            let name = format!("{stem}-{k}");
            if self.dir.join(&name).exists() || self.jobs().iter().any(|j| j.name == name) {
                continue;
            }
            let partial = self.dir.join(format!("{name}{PARTIAL_SUFFIX}"));
            match std::fs::create_dir(&partial) {
                Ok(()) => return Ok((name, partial)),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(format!("creating {}: {e}", partial.display())),
            }
        }
        Err(format!(
            "no free study name `{stem}-K` in {}",
            self.dir.display()
        ))
    }

    /// The directory of the finished started study `name`.
    pub fn finished_dir(&self, name: &str) -> Option<PathBuf> {
        self.jobs()
            .iter()
            .any(|j| j.name == name && matches!(j.state, JobState::Finished { .. }))
            .then(|| self.dir.join(name))
    }
}

/// The sub-directories of `dir` that are not partial.
fn file_dirs(dir: &Path) -> Vec<String> {
    let mut names = entry_names(dir, true);
    names.retain(|n| !n.ends_with(PARTIAL_SUFFIX));
    names
}

/// The declaration of the study `req` asks for, named `name`: the varied parameters uniform
/// over their intervals, every other one fixed at the design's value.
fn declaration(ex: &Explorer, req: &StudyRequest, name: &str) -> Value {
    let names = &ex.rules().names;
    let mut parameters = Map::new();
    for (k, n) in names.iter().enumerate() {
        let value = match req.varied.iter().find(|&&(j, _, _)| j == k) {
            Some(&(_, from, to)) => json!({"uniform": [from, to]}),
            None => json!(req.design[k]),
        };
        parameters.insert(n.clone(), value);
    }
    json!({
        "name": name,
        "kind": req.kind.as_str(),
        "n": req.n,
        "solver_check": req.solver_check,
        "parameters": parameters,
    })
}

/// The study stage's settings of a started study: its declaration on the served model's
/// algorithm at `coverage`, every other setting the stage's default (its seed, 7, included).
fn study_params(ex: &Explorer, declaration: &Value, coverage: f64) -> Result<StudyParams, String> {
    serde_json::from_value(json!({
        "study": declaration,
        "algorithm": ex.identity().algorithm,
        "coverage": coverage,
    }))
    .map_err(|e| format!("the study's settings: {e}"))
}

/// Refuses a start whose declaration is not a valid study of the model (400 naming `n`,
/// `solver_check` or `parameters`), or one with a design the model refuses at a corner of the
/// varied intervals (each design runs under its own generated profile of the study's seed,
/// all of one length): the end of the interval named (`parameters[0].to`), as a sweep names
/// its `to`.
fn validate(ex: &Explorer, req: &StudyRequest, params: &StudyParams) -> Result<(), ApiError> {
    let parameters = pino_study::model_parameters(ex.predictor());
    pino_study::spec::Study::parse(&params.study, &parameters, &ex.index_names()).map_err(|e| {
        let field = match e.field.as_str() {
            "n" | "solver_check" => e.field.clone(),
            _ => "parameters".to_owned(),
        };
        ApiError::bad(field, e.message, "see docs/studies.md")
    })?;
    let names = &ex.rules().names;
    let excitation = Excitation::Seed {
        seed: params.seed,
        id: 0,
    };
    for corner in 0..(1usize << req.varied.len()) {
        let at_to = |i: usize| corner >> i & 1 == 1;
        let mut design = req.design.clone();
        for (i, &(k, from, to)) in req.varied.iter().enumerate() {
            design[k] = if at_to(i) { to } else { from };
        }
        if let Err(mut e) = ex.check_design(&design, excitation) {
            for (i, &(k, _, _)) in req.varied.iter().enumerate() {
                if e.field.as_deref() == Some(&format!("design.{}", names[k])) {
                    let end = format!("parameters[{i}].{}", if at_to(i) { "to" } else { "from" });
                    e.error = format!("study `{end}`: {}", e.error);
                    e.field = Some(end);
                }
            }
            return Err(e);
        }
    }
    Ok(())
}

/// A started study on its way: run on its own pool, then finished, failed or cancelled.
struct Run {
    /// Cleared as it ends, just before its end is listed (so a study started by whoever saw
    /// that end is not refused as a second one).
    flag: RunningFlag,
    studies: Arc<Studies>,
    ex: Arc<Explorer>,
    name: String,
    decl: Value,
    coverage: f64,
    partial: PathBuf,
    progress: Arc<Progress>,
}

impl Run {
    /// Runs the study into its partial directory on the study pool and records how it ended
    /// (a failed or cancelled study's directory removed).
    fn run(self) {
        lower_priority();
        let t0 = Instant::now();
        let outcome = study_pool(self.studies.threads).and_then(|pool| {
            pool.install(|| {
                run_study(
                    &self.ex,
                    &self.decl,
                    self.coverage,
                    &self.partial,
                    &self.progress,
                )
            })
        });
        let state = match outcome {
            _ if self.progress.cancelled() => JobState::Cancelled {
                after_s: t0.elapsed().as_secs_f64(),
            },
            Ok(summary) => {
                let record = Record {
                    declaration: self.decl.clone(),
                    model: self.ex.identity().identity.clone(),
                    summary: summary.clone(),
                    seconds: t0.elapsed().as_secs_f64(),
                };
                match finish(&self.studies.dir, &self.name, &self.partial, &record) {
                    Ok(()) => JobState::Finished { summary },
                    Err(error) => JobState::Failed { error },
                }
            }
            Err(error) => JobState::Failed { error },
        };
        if !matches!(state, JobState::Finished { .. }) {
            let _ = std::fs::remove_dir_all(&self.partial);
        }
        let Run {
            flag,
            studies,
            name,
            ..
        } = self;
        drop(flag);
        studies.set_state(&name, state);
    }
}

/// Runs the study `declaration` through the explorer's surrogate (its calibrations) into `out`,
/// counting its designs in `progress`.
fn run_study(
    ex: &Explorer,
    declaration: &Value,
    coverage: f64,
    out: &Path,
    progress: &Progress,
) -> Result<String, String> {
    let params = study_params(ex, declaration, coverage)?;
    pino_study::run_with(ex.surrogate(), &params, out, Some(progress)).map_err(|e| e.to_string())
}

/// Writes the declaration and the record into `partial`, then renames it to `name`.
fn finish(dir: &Path, name: &str, partial: &Path, record: &Record) -> Result<(), String> {
    let yaml = format!(
        "# Started from the explorer's sweep view. To run it in the pipeline, add this entry\n# to the `study` stage's `matrix: study:` list in the pipeline file (docs/studies.md).\n{}",
        yaml_of(&record.declaration)
    );
    let json = serde_json::to_vec_pretty(record).map_err(|e| e.to_string())?;
    for (file, bytes) in [(DECLARATION_FILE, yaml.as_bytes()), (RECORD_FILE, &json)] {
        atomic_file::write_atomic(&partial.join(file), bytes)
            .map_err(|e| format!("writing {}: {e}", partial.join(file).display()))?;
    }
    let done = dir.join(name);
    std::fs::rename(partial, &done)
        .map_err(|e| format!("renaming {} to {}: {e}", partial.display(), done.display()))
}

/// The path of the file `file` of study `name` of `source`, when that study lists it.
pub fn file_path(
    pipeline: Option<&Pipeline>,
    studies: &Studies,
    source: Source,
    name: &str,
    file: &str,
) -> Option<PathBuf> {
    let dir = match source {
        Source::Explorer => studies.finished_dir(name)?,
        Source::Pipeline => pipeline_study_dir(pipeline?, name)?,
    };
    file_names(&dir)
        .iter()
        .any(|f| f == file)
        .then(|| dir.join(file))
}

/// The limits of a study the sweep view may start, as the page reads them.
pub fn limits_json() -> Value {
    use crate::request::{
        StartedKind, STUDY_MAX_MONTE_CARLO, STUDY_MAX_SENSITIVITY_ROWS, STUDY_MAX_SOLVER_CHECK,
        STUDY_MAX_VARIED,
    };
    json!({
        "kinds": [StartedKind::MonteCarlo.as_str(), StartedKind::Sensitivity.as_str()],
        "max_varied": STUDY_MAX_VARIED,
        "max_n": {
            StartedKind::MonteCarlo.as_str(): STUDY_MAX_MONTE_CARLO,
            StartedKind::Sensitivity.as_str(): STUDY_MAX_SENSITIVITY_ROWS,
        },
        "default_n": {
            StartedKind::MonteCarlo.as_str(): StartedKind::MonteCarlo.default_n(),
            StartedKind::Sensitivity.as_str(): StartedKind::Sensitivity.default_n(),
        },
        "max_solver_check": STUDY_MAX_SOLVER_CHECK,
    })
}

/// The Content-Type a study's file is served with.
pub fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("png") => "image/png",
        Some("csv") => "text/csv; charset=utf-8",
        Some("md") => "text/markdown; charset=utf-8",
        Some("yaml") => "application/yaml",
        Some("json") => "application/json",
        Some("parquet") => "application/vnd.apache.parquet",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(kind: &str) -> StudyView {
        StudyView {
            source: Source::Explorer,
            name: "s".into(),
            kind: kind.into(),
            state: "finished".into(),
            detail: String::new(),
            progress: None,
            declaration: String::new(),
            summary_md: None,
            table: None,
            plots: Vec::new(),
            files: Vec::new(),
            dir: None,
        }
    }

    #[test]
    fn a_study_directory_is_read_as_its_report_table_and_plots() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join(SUMMARY_MD_FILE), "# Study\n").unwrap();
        std::fs::write(d.join("sobol.csv"), "index,factor,total\nq,k,0.5\n").unwrap();
        std::fs::write(d.join("summary.csv"), "not,this,kind\n").unwrap();
        std::fs::write(d.join("sobol.png"), b"png").unwrap();
        std::fs::write(d.join(".hidden"), b"").unwrap();
        std::fs::create_dir(d.join("sub")).unwrap();
        let v = with_outputs(view("sensitivity"), d);
        assert_eq!(v.summary_md.as_deref(), Some("# Study\n"));
        let t = v.table.expect("the sensitivity table");
        assert_eq!(t.file, "sobol.csv");
        assert_eq!(t.rows, [["index", "factor", "total"], ["q", "k", "0.5"]]);
        assert_eq!(v.plots, ["sobol.png"]);
        assert_eq!(
            v.files,
            ["sobol.csv", "sobol.png", "summary.csv", SUMMARY_MD_FILE]
        );
        // A kind without a headline table, or a directory without the file: no table.
        assert!(with_outputs(view("other"), d).table.is_none());
        assert!(with_outputs(view("optimise"), d).table.is_none());
    }

    #[test]
    fn only_finished_studies_with_a_record_are_listed_again_and_names_are_claimed_once() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().to_path_buf();
        let record = Record {
            declaration: json!({"name": "monte_carlo-k-1", "kind": "monte_carlo"}),
            model: "m".into(),
            summary: "done".into(),
            seconds: 1.0,
        };
        let done = root.join("monte_carlo-k-1");
        std::fs::create_dir_all(&done).unwrap();
        std::fs::write(done.join(RECORD_FILE), serde_json::to_vec(&record).unwrap()).unwrap();
        std::fs::create_dir_all(root.join(format!("monte_carlo-k-2{PARTIAL_SUFFIX}"))).unwrap();
        std::fs::create_dir_all(root.join("no-record")).unwrap();
        let studies = Studies::open(root.clone(), 1);
        let listed = studies.list();
        assert_eq!(listed.len(), 1, "{listed:?}");
        assert_eq!(
            (
                listed[0].name.as_str(),
                listed[0].state.as_str(),
                listed[0].detail.as_str()
            ),
            ("monte_carlo-k-1", "finished", "done")
        );
        assert_eq!(studies.finished_dir("monte_carlo-k-1"), Some(done));
        assert_eq!(studies.finished_dir("monte_carlo-k-2"), None);
        // -1 is finished and -2 is being written: the next name is -3, then -4.
        let (a, pa) = studies.claim("monte_carlo-k").unwrap();
        let (b, _) = studies.claim("monte_carlo-k").unwrap();
        assert_eq!(
            (a.as_str(), b.as_str()),
            ("monte_carlo-k-3", "monte_carlo-k-4")
        );
        assert!(pa.is_dir() && pa.ends_with(format!("monte_carlo-k-3{PARTIAL_SUFFIX}")));
        // A cancelled (or failed) study keeps its name though its directory is gone.
        studies.jobs().push(Job {
            name: "monte_carlo-k-5".into(),
            declaration: Value::Null,
            state: JobState::Cancelled { after_s: 1.0 },
        });
        assert_eq!(studies.claim("monte_carlo-k").unwrap().0, "monte_carlo-k-6");
    }

    #[test]
    fn finishing_renames_the_partial_directory_with_the_declaration_beside_the_files() {
        let dir = tempfile::tempdir().unwrap();
        let partial = dir.path().join(format!("s-1{PARTIAL_SUFFIX}"));
        std::fs::create_dir(&partial).unwrap();
        std::fs::write(partial.join(SUMMARY_MD_FILE), "# s\n").unwrap();
        let record = Record {
            declaration: json!({"name": "s-1", "kind": "sensitivity", "n": 16}),
            model: "m".into(),
            summary: "ok".into(),
            seconds: 2.0,
        };
        finish(dir.path(), "s-1", &partial, &record).unwrap();
        assert!(!partial.exists());
        let done = dir.path().join("s-1");
        let yaml: Value =
            serde_yaml::from_str(&std::fs::read_to_string(done.join(DECLARATION_FILE)).unwrap())
                .unwrap();
        assert_eq!(
            yaml, record.declaration,
            "the YAML is the declaration itself"
        );
        let back: Record =
            serde_json::from_str(&std::fs::read_to_string(done.join(RECORD_FILE)).unwrap())
                .unwrap();
        assert_eq!(back, record);
        assert!(done.join(SUMMARY_MD_FILE).is_file());
    }
}
