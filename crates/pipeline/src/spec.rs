//! The pipeline file: parsing, validation, `--set` overrides and matrix expansion.
//!
//! A pipeline file is YAML with the top-level keys `bin_dir`, `executor`, `constants` (shared
//! values, [`crate::constants`]) and `stages` (see the README); a stage may carry `resources:`
//! for the Slurm executor ([`crate::executor`]).
//! Parsing is strict (`deny_unknown_fields`), so a misspelt key is an error at its line. After
//! parsing, the semantic checks run: names, dependencies (every input names a stage), cycles,
//! shard counts, matrix keys, paths (relative, inside the workspace, also after following
//! symbolic links) and `--set` overrides (the
//! stage and key must exist, the value must have the parameter's type; an integer may stand
//! for a float). Every error names the file and the line.
//!
//! Parameters are arbitrary YAML values held as JSON values whose objects have sorted keys,
//! so `serde_json::to_string` of them is their canonical form (hashing and the context file).

use crate::executor::{ExecutorKind, Resources};
use crate::locate::Locator;
use crate::{Error, Result};
use serde::Deserialize;
use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

mod extend;

/// A string-keyed mapping that rejects duplicate keys (YAML allows them silently; a stage
/// or parameter defined twice is almost always a mistake). The error carries the position.
struct UniqueMap<V>(BTreeMap<String, V>);

impl<'de, V: Deserialize<'de>> Deserialize<'de> for UniqueMap<V> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Vis<V>(std::marker::PhantomData<V>);
        impl<'de, V: Deserialize<'de>> serde::de::Visitor<'de> for Vis<V> {
            type Value = UniqueMap<V>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a mapping")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut m: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let mut out = BTreeMap::new();
                while let Some(k) = m.next_key::<String>()? {
                    if out.contains_key(&k) {
                        return Err(serde::de::Error::custom(format!("duplicate key `{k}`")));
                    }
                    let v = m.next_value()?;
                    out.insert(k, v);
                }
                Ok(UniqueMap(out))
            }
        }
        d.deserialize_map(Vis(std::marker::PhantomData))
    }
}

impl<V> Default for UniqueMap<V> {
    fn default() -> Self {
        Self(BTreeMap::new())
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPipeline {
    /// The workspace root, relative to the file's directory (default: that directory); read
    /// by [`locate`] when no workspace is given.
    #[serde(default)]
    workspace: Option<String>,
    #[serde(default)]
    bin_dir: Option<String>,
    #[serde(default)]
    executor: Option<ExecutorKind>,
    /// Shared values stages reference as `${constants.NAME}` ([`crate::constants`]).
    #[serde(default)]
    constants: UniqueMap<Value>,
    stages: UniqueMap<RawStage>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStage {
    /// Another stage this one starts from ([`extend`]).
    #[serde(default)]
    extends: Option<String>,
    /// Required unless the stage extends another.
    #[serde(default)]
    cmd: Option<Vec<String>>,
    #[serde(default)]
    params: Option<UniqueMap<Value>>,
    #[serde(default)]
    inputs: Option<UniqueMap<Upstreams>>,
    #[serde(default)]
    shards: Option<usize>,
    #[serde(default)]
    matrix: Option<UniqueMap<Vec<Value>>>,
    #[serde(default)]
    resources: Option<Resources>,
    #[serde(default)]
    check: Option<bool>,
}

/// What one input reads: an upstream stage, or several in order (`models: [train,
/// train-rates]`: the directories of every unit of each, one stage after the other).
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum Upstreams {
    One(String),
    Many(Vec<String>),
}

impl Upstreams {
    fn into_vec(self) -> Vec<String> {
        match self {
            Upstreams::One(s) => vec![s],
            Upstreams::Many(v) => v,
        }
    }
}

/// One matrix expansion of a stage (the stage itself when it has no matrix).
#[derive(Debug, Clone)]
pub struct Expansion {
    /// `train[algorithm=3]`, or the stage name without a matrix.
    pub name: String,
    /// Resolved parameters: defaults, `--set` overrides, the matrix values.
    pub params: Value,
}

/// A validated stage definition.
#[derive(Debug, Clone)]
pub struct Stage {
    /// The stage's name (a key of `stages:`).
    pub name: String,
    /// Line of the name in the pipeline file.
    pub line: usize,
    /// The argument list; `cmd[0]` is resolved by [`Pipeline::resolve_executable`].
    pub cmd: Vec<String>,
    /// Input name -> the upstream stages it reads, in order (one, or several whose units'
    /// directories follow each other).
    pub inputs: BTreeMap<String, Vec<String>>,
    /// Number of shard processes (1 when unsharded).
    pub shards: usize,
    /// The matrix expansions in order (one when there is no matrix).
    pub expansions: Vec<Expansion>,
    /// The `--set` overrides applied to this stage, as given (`KEY=VALUE`).
    pub overrides: Vec<String>,
    /// What its Slurm jobs ask for (`resources:`; not part of the identity).
    pub resources: Resources,
    /// Whether the stage has a check mode the orchestrator runs before anything runs
    /// (`check: true`; [`crate::check`]).
    pub check: bool,
    /// The stage it starts from (`extends:`), whose fields it inherits.
    pub extends: Option<String>,
}

impl Stage {
    /// Whether the stage runs the stage binary `command`: its `cmd[0]` is that name or a path
    /// ending in it (`study`, `./target/release/study`).
    pub fn runs(&self, command: &str) -> bool {
        self.cmd
            .first()
            .and_then(|c| std::path::Path::new(c).file_name())
            .is_some_and(|n| n == command)
    }
}

/// A loaded, validated pipeline with its stages in dependency order.
#[derive(Debug, Clone)]
pub struct Pipeline {
    /// The pipeline file as named on the command line (for messages).
    pub file: String,
    /// Key of this pipeline in the lock record: its path relative to the workspace.
    pub key: String,
    /// Absolute workspace root.
    pub workspace: PathBuf,
    /// Absolute directory searched first for bare command names.
    pub bin_dir: PathBuf,
    /// Stages in topological order (ties broken by name).
    pub stages: Vec<Stage>,
    /// Absolute directory of the pipeline file (YAML paths are relative to it).
    pub base: PathBuf,
    /// The file's `executor:` (local when absent); `run --executor` overrides it.
    pub executor: ExecutorKind,
    text: String,
}

/// Options that shape how a pipeline is loaded.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// `--bin-dir` or `PINO_BIN_DIR` (absolute or relative to the current directory).
    pub bin_dir: Option<PathBuf>,
    /// `--set STAGE.KEY=VALUE` overrides, in order.
    pub sets: Vec<String>,
}

fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// Lexically normalises `p` (no filesystem access): drops `.`, resolves `..`.
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Whether relative path `rel`, taken from `base`, stays inside `workspace` (lexically).
fn stays_inside(workspace: &Path, base: &Path, rel: &str) -> bool {
    let p = Path::new(rel);
    if p.is_absolute() {
        return false;
    }
    // `..` may not climb above the workspace even transiently.
    let mut depth: isize = base
        .strip_prefix(workspace)
        .map_or(0, |b| b.components().count() as isize);
    for c in p.components() {
        match c {
            Component::ParentDir => depth -= 1,
            Component::Normal(_) => depth += 1,
            _ => {}
        }
        if depth < 0 {
            return false;
        }
    }
    normalize(&base.join(p)).starts_with(workspace)
}

/// Where `p` really is: its longest existing prefix as the kernel resolves it (every symbolic
/// link followed, `..` applied after the link), the rest appended lexically. A dangling link is
/// followed through its text, so a link to a place that does not exist yet is judged too.
fn resolve(p: &Path, hops: usize) -> PathBuf {
    let mut head = p.to_path_buf();
    let mut tail: Vec<std::ffi::OsString> = Vec::new();
    let rejoin = |mut r: PathBuf, tail: &[std::ffi::OsString]| {
        for c in tail.iter().rev() {
            r.push(c);
        }
        normalize(&r)
    };
    loop {
        if let Ok(real) = head.canonicalize() {
            return rejoin(real, &tail);
        }
        if hops < 40 {
            if let Ok(target) = std::fs::read_link(&head) {
                let parent = head.parent().map(Path::to_path_buf).unwrap_or_default();
                return resolve(&rejoin(parent.join(target), &tail), hops + 1);
            }
        }
        match head.file_name() {
            Some(name) => {
                tail.push(name.to_owned());
                head.pop();
            }
            None => return normalize(p),
        }
    }
}

/// Why relative path `rel`, taken from `base`, is not inside `workspace`: it leaves it
/// lexically (absolute, or `..` climbing out), or a symbolic link on its way points outside
/// (the real path of the existing part is outside the workspace's real path); `None` when it
/// stays inside.
fn escape(workspace: &Path, base: &Path, rel: &str) -> Option<String> {
    if !stays_inside(workspace, base, rel) {
        return Some(format!(
            "must be a relative path inside the workspace {}",
            workspace.display()
        ));
    }
    let root = workspace
        .canonicalize()
        .unwrap_or_else(|_| workspace.to_path_buf());
    let real = resolve(&base.join(rel), 0);
    (!real.starts_with(&root)).then(|| {
        format!(
            "leads through a symbolic link to {}, outside the workspace {}",
            real.display(),
            root.display()
        )
    })
}

/// The type name of a parameter value, as messages show it.
pub fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(n) if n.is_f64() => "float",
        Value::Number(_) => "integer",
        Value::String(_) => "string",
        Value::Array(_) => "list",
        Value::Object(_) => "mapping",
    }
}

/// `an integer`, `a float`.
fn a(kind: &str) -> String {
    if kind.starts_with(['a', 'e', 'i', 'o', 'u']) {
        format!("an {kind}")
    } else {
        format!("a {kind}")
    }
}

/// Converts a `--set` value to the type of `existing`, or says why it cannot.
fn coerce(existing: &Value, raw: &str, parsed: Value) -> std::result::Result<Value, String> {
    match (existing, &parsed) {
        (Value::Null, _) => Ok(parsed),
        (Value::String(_), Value::String(_)) => Ok(parsed),
        // A string parameter takes the text as written (`--set s.name=123` is "123").
        (Value::String(_), _) => Ok(Value::String(raw.to_owned())),
        (Value::Number(e), Value::Number(p)) if e.is_f64() => p
            .as_f64()
            .and_then(serde_json::Number::from_f64)
            .map(Value::Number)
            .ok_or_else(|| format!("`{raw}` is not a finite number")),
        (Value::Number(_), Value::Number(p)) if !p.is_f64() => Ok(parsed),
        (e, p) if kind(e) == kind(p) => Ok(parsed),
        (e, p) => Err(format!(
            "the parameter is {} but `{raw}` is {}",
            a(kind(e)),
            a(kind(p))
        )),
    }
}

/// The VALUE of `--set set` (YAML) converted to the type of `existing`; `what` names the
/// target in messages, `at` places a type error at its line.
fn override_value(
    set: &str,
    raw: &str,
    existing: &Value,
    what: &str,
    at: impl FnOnce(String) -> Error,
) -> Result<Value> {
    let parsed: Value = serde_yaml::from_str(raw)
        .map_err(|e| Error::Usage(format!("--set {set}: `{raw}` is not a YAML value: {e}")))?;
    coerce(existing, raw, parsed)
        .map_err(|why| at(format!("--set {set}: wrong type for {what}: {why}")))
}

/// Renders a matrix value inside an expansion name: strings bare, a mapping with a string
/// `name` by that name (a declared study: `study[study=wheel_unloading]`), others as JSON.
fn render(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Object(m) => match m.get("name") {
            Some(Value::String(s)) => s.clone(),
            _ => v.to_string(),
        },
        other => other.to_string(),
    }
}

/// The pipeline file being loaded, for errors that name it and a line of it.
struct SourceFile<'a> {
    /// The file as named on the command line.
    display: &'a str,
    /// Finds the lines of stages, fields and words.
    loc: Locator<'a>,
}

impl SourceFile<'_> {
    /// A semantic error at `line`.
    fn err(&self, line: usize, message: String) -> Error {
        Error::Spec {
            file: self.display.to_owned(),
            line,
            message,
        }
    }

    /// The names of `map`'s keys, for "known: ..." lists in messages.
    fn known<V>(map: &BTreeMap<String, V>) -> String {
        map.keys()
            .map(String::as_str)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A stage while the pipeline is loaded: its definition, and its parameters and matrix before
/// the overrides, constants and expansion are applied.
struct Draft {
    stage: Stage,
    params: Map<String, Value>,
    matrix: BTreeMap<String, Vec<Value>>,
}

/// Parses the YAML strictly; an error names the file, line and column (a duplicate key at the
/// duplicate itself).
fn parse_yaml(text: &str, display: &str) -> Result<RawPipeline> {
    serde_yaml::from_str(text).map_err(|e| {
        let (mut line, mut column) = e.location().map_or((1, 1), |l| (l.line(), l.column()));
        // serde_yaml places a duplicate-key error at the mapping's start; point at the
        // duplicate itself when the text shows it.
        let msg = e.to_string();
        if let Some(key) = msg
            .split("duplicate key `")
            .nth(1)
            .and_then(|r| r.split('`').next())
        {
            if let Some(l) = Locator::new(text).duplicate_line(line, key) {
                (line, column) = (l, 1);
            }
        }
        Error::Yaml {
            file: display.to_owned(),
            line,
            column,
            message: msg,
        }
    })
}

/// The workspace and the pipeline file a command names: with a `workspace`, that one and
/// `file` relative to it (unless absolute); without, `file` relative to the current
/// directory and the workspace its `workspace:` (relative to the file's directory: `.` or a
/// directory above) or else the file's own directory. The `pipeline` command's `-C`/`-f` and
/// the Python package's `Pipeline(path, workspace=)` resolve through it, so a pipeline file
/// opened from anywhere runs in the same workspace.
pub fn locate(file: &Path, workspace: Option<&Path>) -> Result<(PathBuf, PathBuf)> {
    if let Some(ws) = workspace {
        let file = if file.is_absolute() {
            file.to_owned()
        } else {
            ws.join(file)
        };
        return Ok((ws.to_owned(), file));
    }
    let display = file.display().to_string();
    let text = std::fs::read_to_string(file)
        .map_err(|e| Error::Usage(format!("cannot read pipeline file {display}: {e}")))?;
    let raw = parse_yaml(&text, &display)?;
    let abs = normalize(&std::path::absolute(file).map_err(|e| Error::io(file, e))?);
    let dir = abs.parent().unwrap_or(Path::new("/")).to_path_buf();
    let Some(rel) = raw.workspace else {
        return Ok((dir, file.to_owned()));
    };
    let ws = normalize(&dir.join(&rel));
    if Path::new(&rel).is_absolute() || !dir.starts_with(&ws) {
        let src = SourceFile {
            display: &display,
            loc: Locator::new(&text),
        };
        return Err(src.err(
            src.loc.top_line("workspace"),
            format!("workspace `{rel}`: allowed the file's directory (`.`) or one above it (`..`, `../..`), relative to the file"),
        ));
    }
    Ok((ws, file.to_owned()))
}

/// Checks one stage's own fields (its name, command, shards, resources, input names and
/// matrix keys) and drafts it.
fn draft_stage(
    src: &SourceFile,
    workspace: &Path,
    base: &Path,
    name: String,
    rs: RawStage,
) -> Result<Draft> {
    let loc = &src.loc;
    let line = loc.stage_line(&name);
    if !valid_name(&name) {
        return Err(src.err(
            line,
            format!("stage name `{name}` may only use letters, digits, `_` and `-`"),
        ));
    }
    let cmd = stage_command(src, workspace, base, &name, rs.cmd)?;
    let shards = rs.shards.unwrap_or(1);
    if shards == 0 {
        return Err(src.err(
            loc.field_line(&name, "shards"),
            format!("stage `{name}`: `shards` must be at least 1"),
        ));
    }
    let resources = rs.resources.unwrap_or_default();
    resources.check().map_err(|why| {
        src.err(
            loc.field_line(&name, "resources"),
            format!("stage `{name}`: {why}"),
        )
    })?;
    let inputs = stage_inputs(src, &name, rs.inputs)?;
    let params: Map<String, Value> = rs
        .params
        .map(|m| m.0.into_iter().collect())
        .unwrap_or_default();
    let matrix = rs.matrix.map(|m| m.0).unwrap_or_default();
    check_matrix(src, &name, &params, &matrix)?;
    Ok(Draft {
        stage: Stage {
            name,
            line,
            cmd,
            inputs,
            shards,
            expansions: Vec::new(),
            overrides: Vec::new(),
            resources,
            check: rs.check.unwrap_or(false),
            extends: None,
        },
        params,
        matrix,
    })
}

/// A stage's `cmd`: it names a program, and a program given by path stays inside the workspace.
fn stage_command(
    src: &SourceFile,
    workspace: &Path,
    base: &Path,
    name: &str,
    cmd: Option<Vec<String>>,
) -> Result<Vec<String>> {
    let loc = &src.loc;
    let cmd = cmd.unwrap_or_default();
    if cmd.is_empty() || cmd[0].is_empty() {
        return Err(src.err(
            loc.field_line(name, "cmd"),
            format!("stage `{name}`: `cmd` must name a program"),
        ));
    }
    let exe = &cmd[0];
    if exe.contains('/') {
        if let Some(why) = escape(workspace, base, exe) {
            return Err(src.err(
                loc.field_line(name, "cmd"),
                format!("stage `{name}`: command `{exe}` {why} (or use a bare name)"),
            ));
        }
    }
    Ok(cmd)
}

/// A stage's `inputs`: valid names, each naming at least one stage and none twice.
fn stage_inputs(
    src: &SourceFile,
    name: &str,
    raw: Option<UniqueMap<Upstreams>>,
) -> Result<BTreeMap<String, Vec<String>>> {
    let loc = &src.loc;
    let inputs: BTreeMap<String, Vec<String>> = raw
        .map(|m| m.0)
        .unwrap_or_default()
        .into_iter()
        .map(|(k, v)| (k, v.into_vec()))
        .collect();
    if let Some(input) = inputs.keys().find(|i| !valid_name(i)) {
        return Err(src.err(
            loc.field_line(name, "inputs"),
            format!(
                "stage `{name}`: input name `{input}` may only use letters, digits, `_` and `-`"
            ),
        ));
    }
    for (input, ups) in &inputs {
        let mut seen = std::collections::BTreeSet::new();
        let problem = if ups.is_empty() {
            Some("names no stage: give one stage or a list of stages".to_owned())
        } else {
            ups.iter()
                .find(|u| !seen.insert(u.as_str()))
                .map(|u| format!("names stage `{u}` twice"))
        };
        if let Some(problem) = problem {
            return Err(src.err(
                loc.field_line(name, "inputs"),
                format!("stage `{name}`: input `{input}` {problem}"),
            ));
        }
    }
    Ok(inputs)
}

/// A stage's `matrix`: no key also a parameter, every key with values, no value twice.
fn check_matrix(
    src: &SourceFile,
    name: &str,
    params: &Map<String, Value>,
    matrix: &BTreeMap<String, Vec<Value>>,
) -> Result<()> {
    let loc = &src.loc;
    for (k, values) in matrix {
        let l = loc.word_line(name, "matrix", k);
        if params.contains_key(k) {
            return Err(src.err(
                l,
                format!(
                    "stage `{name}`: matrix key `{k}` is also a parameter; keep it in one place"
                ),
            ));
        }
        if values.is_empty() {
            return Err(src.err(l, format!("stage `{name}`: matrix key `{k}` has no values")));
        }
        let mut seen = std::collections::BTreeSet::new();
        if let Some(v) = values.iter().find(|v| !seen.insert(render(v))) {
            return Err(src.err(
                l,
                format!("stage `{name}`: matrix key `{k}` has the value `{}` twice (values name units: give each its own)", render(v)),
            ));
        }
    }
    Ok(())
}

/// Every input names a stage of the pipeline.
fn check_inputs(src: &SourceFile, drafts: &BTreeMap<String, Draft>) -> Result<()> {
    for (name, draft) in drafts {
        for (input, up) in draft
            .stage
            .inputs
            .iter()
            .flat_map(|(i, ups)| ups.iter().map(move |u| (i, u)))
        {
            if !drafts.contains_key(up) {
                return Err(src.err(
                    src.loc.word_line(name, "inputs", up),
                    format!(
                        "stage `{name}`: input `{input}` depends on unknown stage `{up}` (stages: {})",
                        SourceFile::known(drafts)
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Applies one `--set STAGE.KEY=VALUE` (or `constants.NAME[.KEY]=VALUE`): the target must
/// exist, and the value takes the type of the value it replaces.
fn apply_set(
    src: &SourceFile,
    set: &str,
    constants: &mut Map<String, Value>,
    drafts: &mut BTreeMap<String, Draft>,
) -> Result<()> {
    let usage = || Error::Usage(format!("--set `{set}`: expected STAGE.KEY=VALUE"));
    let (lhs, raw_value) = set.split_once('=').ok_or_else(usage)?;
    let (sname, key) = lhs.split_once('.').ok_or_else(usage)?;
    if sname == crate::constants::SECTION {
        return set_constant(src, set, key, raw_value, constants);
    }
    let Some(draft) = drafts.get_mut(sname) else {
        return Err(src.err(
            src.loc.top_line("stages"),
            format!(
                "--set {set}: no stage `{sname}` in this pipeline (stages: {})",
                SourceFile::known(drafts)
            ),
        ));
    };
    if draft.matrix.contains_key(key) {
        return Err(src.err(
            src.loc.word_line(sname, "matrix", key),
            format!("--set {set}: `{key}` is a matrix key of stage `{sname}`; run one expansion with `pipeline run '{sname}[{key}=...]'`"),
        ));
    }
    let Some(existing) = draft.params.get(key) else {
        let known: Vec<&str> = draft.params.keys().map(String::as_str).collect();
        return Err(src.err(
            src.loc.field_line(sname, "params"),
            format!(
                "--set {set}: stage `{sname}` has no parameter `{key}` (parameters: {})",
                known.join(", ")
            ),
        ));
    };
    if let Some(name) = crate::constants::reference(existing) {
        return Err(src.err(
            src.loc.word_line(sname, "params", key),
            format!("--set {set}: `{sname}.{key}` takes its value from constant `{name}`; set it for every stage with `--set constants.{name}=...`"),
        ));
    }
    let value = override_value(set, raw_value, existing, &format!("`{sname}.{key}`"), |m| {
        src.err(src.loc.word_line(sname, "params", key), m)
    })?;
    draft.params.insert(key.to_owned(), value);
    draft.stage.overrides.push(format!("{key}={raw_value}"));
    Ok(())
}

/// `--set constants.NAME=VALUE`, or `constants.NAME.KEY=VALUE` for one entry of a mapping
/// constant (its consumer checks the names: a system description's parameter overrides, for
/// one).
fn set_constant(
    src: &SourceFile,
    set: &str,
    key: &str,
    raw_value: &str,
    constants: &mut Map<String, Value>,
) -> Result<()> {
    let line = src.loc.top_line(crate::constants::SECTION);
    let what = format!("constant `{key}`");
    if let Some((name, sub)) = key.split_once('.') {
        let Some(Value::Object(map)) = constants.get_mut(name) else {
            return Err(src.err(
                line,
                format!("--set {set}: `constants.{name}` is not a mapping constant, so `{sub}` cannot be set inside it"),
            ));
        };
        let existing = map.get(sub).cloned().unwrap_or(Value::Null);
        let value = override_value(set, raw_value, &existing, &what, |m| src.err(line, m))?;
        map.insert(sub.to_owned(), value);
        return Ok(());
    }
    let Some(existing) = constants.get(key) else {
        let known: Vec<&str> = constants.keys().map(String::as_str).collect();
        return Err(src.err(
            line,
            format!(
                "--set {set}: no constant `{key}` in this pipeline (constants: {})",
                known.join(", ")
            ),
        ));
    };
    let value = override_value(set, raw_value, existing, &what, |m| src.err(line, m))?;
    constants.insert(key.to_owned(), value);
    Ok(())
}

/// Every `${constants.NAME}` of the stage's parameters becomes the (possibly overridden)
/// value; so does a whole command argument that is one (a system description's path, say,
/// so the file it names is hashed as any argument).
fn substitute_constants(
    src: &SourceFile,
    draft: &mut Draft,
    constants: &Map<String, Value>,
) -> Result<()> {
    let known = || {
        constants
            .keys()
            .map(String::as_str)
            .collect::<Vec<_>>()
            .join(", ")
    };
    let stage = &mut draft.stage;
    for (key, value) in draft.params.iter_mut() {
        crate::constants::substitute(value, constants).map_err(|name| {
            src.err(
                src.loc.word_line(&stage.name, "params", key),
                format!(
                    "stage `{}`: parameter `{key}` refers to unknown constant `{name}` (constants: {})",
                    stage.name,
                    known()
                ),
            )
        })?;
    }
    for arg in stage.cmd.iter_mut().skip(1) {
        let Some(name) =
            crate::constants::reference(&Value::String(arg.clone())).map(str::to_owned)
        else {
            continue;
        };
        let line = src.loc.field_line(&stage.name, "cmd");
        *arg = match constants.get(&name) {
            Some(Value::String(text)) => text.clone(),
            Some(v @ (Value::Number(_) | Value::Bool(_))) => v.to_string(),
            Some(_) => {
                return Err(src.err(line, format!("stage `{}`: command argument `${{constants.{name}}}` must name a string or number constant, not a list or mapping", stage.name)))
            }
            None => {
                return Err(src.err(line, format!("stage `{}`: command argument refers to unknown constant `{name}` (constants: {})", stage.name, known())));
            }
        };
    }
    Ok(())
}

/// The stage's expansions: the cartesian product of its matrix values over the keys in
/// sorted order, each named `stage[key=value,...]` (the stage's own name without a matrix).
fn expand_matrix(draft: &mut Draft) {
    let mut combos: Vec<Vec<(String, Value)>> = vec![Vec::new()];
    for (k, values) in &draft.matrix {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((k.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    let stage = &mut draft.stage;
    stage.expansions = combos
        .into_iter()
        .map(|combo| {
            let mut p = draft.params.clone();
            let label: Vec<String> = combo
                .iter()
                .map(|(k, v)| format!("{k}={}", render(v)))
                .collect();
            for (k, v) in combo {
                p.insert(k, v);
            }
            Expansion {
                name: if label.is_empty() {
                    stage.name.clone()
                } else {
                    format!("{}[{}]", stage.name, label.join(","))
                },
                params: Value::Object(p),
            }
        })
        .collect();
}

/// The directory of the stage programs: the command line wins, then the environment (both in
/// `opts`), then the file's `bin_dir` (which must stay inside the workspace), then
/// `target/release` of the workspace.
fn resolve_bin_dir(
    src: &SourceFile,
    workspace: &Path,
    base: &Path,
    opts: &LoadOptions,
    file_dir: Option<&str>,
) -> Result<PathBuf> {
    if let Some(d) = file_dir {
        if let Some(why) = escape(workspace, base, d) {
            return Err(src.err(src.loc.top_line("bin_dir"), format!("bin_dir `{d}` {why}")));
        }
    }
    Ok(match (&opts.bin_dir, file_dir) {
        (Some(d), _) => std::path::absolute(d).map_err(|e| Error::io(d, e))?,
        (None, Some(d)) => normalize(&base.join(d)),
        (None, None) => workspace.join("target").join("release"),
    })
}

/// The drafted stages, each after the stages it reads; a dependency cycle is refused at the
/// line of its first edge.
fn in_dependency_order(
    src: &SourceFile,
    mut drafts: BTreeMap<String, Draft>,
) -> Result<Vec<Stage>> {
    let order = topo_order(
        &drafts
            .iter()
            .map(|(k, d)| {
                (
                    k.clone(),
                    d.stage.inputs.values().flatten().cloned().collect(),
                )
            })
            .collect(),
    )
    .map_err(|cycle| {
        src.err(
            src.loc.word_line(&cycle[0], "inputs", &cycle[1]),
            format!("dependency cycle: {}", cycle.join(" -> ")),
        )
    })?;
    Ok(order
        .into_iter()
        .map(|n| drafts.remove(&n).expect("known stage").stage)
        .collect())
}

impl Pipeline {
    /// Reads, parses and validates the pipeline file `file` (relative to the current
    /// directory) of the workspace `workspace`.
    ///
    /// The phases, in order: the YAML, each stage's own fields (`draft_stage`), the
    /// dependencies, the `--set` overrides (`apply_set`), the constants
    /// (`substitute_constants`), the matrix (`expand_matrix`) and the dependency order.
    pub fn load(workspace: &Path, file: &Path, opts: &LoadOptions) -> Result<Self> {
        let display = file.display().to_string();
        let text = std::fs::read_to_string(file)
            .map_err(|e| Error::Usage(format!("cannot read pipeline file {display}: {e}")))?;
        let workspace = std::path::absolute(workspace).map_err(|e| Error::io(workspace, e))?;
        let abs_file = normalize(&std::path::absolute(file).map_err(|e| Error::io(file, e))?);
        let key = abs_file
            .strip_prefix(&workspace)
            .map(|p| p.to_string_lossy().into_owned())
            .unwrap_or_else(|_| abs_file.to_string_lossy().into_owned());
        let base = abs_file.parent().unwrap_or(&workspace).to_path_buf();

        let raw = parse_yaml(&text, &display)?;
        let src = SourceFile {
            display: &display,
            loc: Locator::new(&text),
        };

        let bin_dir = resolve_bin_dir(&src, &workspace, &base, opts, raw.bin_dir.as_deref())?;

        let mut constants: Map<String, Value> = raw.constants.0.into_iter().collect();
        let mut drafts = BTreeMap::new();
        let mut extending = BTreeMap::new();
        for (name, rs) in raw.stages.0 {
            if rs.extends.is_some() {
                extending.insert(name, rs);
                continue;
            }
            let draft = draft_stage(&src, &workspace, &base, name.clone(), rs)?;
            drafts.insert(name, draft);
        }
        // The `--set`s of a stage another extends apply before it is copied; those of an
        // extending stage after.
        let (later_sets, sets): (Vec<&String>, Vec<&String>) = opts
            .sets
            .iter()
            .partition(|set| extending.contains_key(extend::set_target(set)));
        for set in sets {
            apply_set(&src, set, &mut constants, &mut drafts)?;
        }
        let extenders = extending.keys().cloned().collect();
        for (name, rs) in extending {
            let draft = extend::draft_extending(
                &src,
                &workspace,
                &base,
                &drafts,
                &extenders,
                name.clone(),
                rs,
            )?;
            drafts.insert(name, draft);
        }
        check_inputs(&src, &drafts)?;
        for set in later_sets {
            apply_set(&src, set, &mut constants, &mut drafts)?;
        }
        for draft in drafts.values_mut() {
            substitute_constants(&src, draft, &constants)?;
            expand_matrix(draft);
        }

        let stages = in_dependency_order(&src, drafts)?;
        Ok(Self {
            file: display,
            key,
            workspace,
            bin_dir,
            stages,
            base,
            executor: raw.executor.unwrap_or_default(),
            text,
        })
    }

    /// The stage called `name`.
    pub fn stage(&self, name: &str) -> Option<&Stage> {
        self.stages.iter().find(|s| s.name == name)
    }

    /// Index of the stage called `name` in [`Pipeline::stages`].
    pub fn index(&self, name: &str) -> Option<usize> {
        self.stages.iter().position(|s| s.name == name)
    }

    /// The stages that run the stage binary `command` (see [`Stage::runs`]) with their
    /// indices in [`Pipeline::stages`], in dependency order: every `study` stage, whatever its
    /// name.
    pub fn stages_running<'a>(
        &'a self,
        command: &'a str,
    ) -> impl Iterator<Item = (usize, &'a Stage)> + 'a {
        self.stages
            .iter()
            .enumerate()
            .filter(move |(_, s)| s.runs(command))
    }

    /// `FILE:LINE` of stage `stage`'s parameter `key` in the pipeline file (the stage's
    /// `params:` line when the key is not written there): where a check's complaint about a
    /// parameter points.
    pub fn param_location(&self, stage: &str, key: &str) -> String {
        let loc = Locator::new(&self.text);
        let inherited = || {
            let base = self.stage(stage)?.extends.as_deref()?;
            loc.word_line_if(base, "params", key)
        };
        let line = loc
            .word_line_if(stage, "params", key)
            .or_else(inherited)
            .unwrap_or_else(|| loc.word_line(stage, "params", key));
        format!("{}:{line}", self.file)
    }

    /// Resolves the stage's `cmd[0]`: a path with a `/` relative to the pipeline file's
    /// directory; a bare name in `bin_dir`, then on `PATH`. Missing: bad input at the
    /// `cmd` line.
    pub fn resolve_executable(&self, stage: &Stage) -> Result<PathBuf> {
        let exe = &stage.cmd[0];
        let base = &self.base;
        let found = if exe.contains('/') {
            Some(normalize(&base.join(exe))).filter(|p| p.is_file())
        } else {
            std::iter::once(self.bin_dir.clone())
                .chain(
                    std::env::var_os("PATH")
                        .iter()
                        .flat_map(std::env::split_paths),
                )
                .map(|d| d.join(exe))
                .find(|p| p.is_file())
        };
        found.ok_or_else(|| Error::Spec {
            file: self.file.clone(),
            line: Locator::new(&self.text).field_line(&stage.name, "cmd"),
            message: format!(
                "stage `{}`: executable `{exe}` not found (looked in {} and on PATH; build it, or set --bin-dir / PINO_BIN_DIR)",
                stage.name,
                self.bin_dir.display()
            ),
        })
    }

    /// Args after `cmd[0]` that name files relative to the workspace: hashed into the
    /// identity too, so that editing a script passed to an interpreter makes the stage stale.
    pub fn file_args(&self, stage: &Stage) -> Vec<PathBuf> {
        stage.cmd[1..]
            .iter()
            .filter(|a| !a.starts_with('-') && !Path::new(a).is_absolute())
            .map(|a| self.workspace.join(a))
            .filter(|p| p.is_file())
            .collect()
    }
}

/// Topological order of `deps` (node -> its upstream nodes), ties broken by name; on a cycle,
/// the cycle as a node list whose last element equals its first.
fn topo_order(
    deps: &BTreeMap<String, Vec<String>>,
) -> std::result::Result<Vec<String>, Vec<String>> {
    let mut order = Vec::new();
    let mut done = std::collections::BTreeSet::new();
    while done.len() < deps.len() {
        let ready: Vec<&String> = deps
            .iter()
            .filter(|(n, ups)| !done.contains(*n) && ups.iter().all(|u| done.contains(u)))
            .map(|(n, _)| n)
            .collect();
        if ready.is_empty() {
            // Walk upstream from any remaining node until a node repeats.
            let mut path: Vec<String> = vec![deps
                .keys()
                .find(|n| !done.contains(*n))
                .expect("remaining")
                .clone()];
            loop {
                let last = path.last().expect("nonempty");
                let next = deps[last]
                    .iter()
                    .find(|u| !done.contains(*u))
                    .expect("a blocked node has a blocked input")
                    .clone();
                if let Some(pos) = path.iter().position(|p| *p == next) {
                    let mut cycle = path[pos..].to_vec();
                    cycle.push(next);
                    // `a -> b` reads "a takes input from b".
                    return Err(cycle);
                }
                path.push(next);
            }
        }
        for n in ready {
            done.insert(n.clone());
            order.push(n.clone());
        }
    }
    Ok(order)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Loads `text` as a pipeline file of a fresh workspace, with the `--set`s `sets`.
    pub(crate) fn load(text: &str, sets: &[&str]) -> Result<Pipeline> {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.yaml");
        std::fs::write(&f, text).unwrap();
        let opts = LoadOptions {
            bin_dir: None,
            sets: sets.iter().map(|s| s.to_string()).collect(),
        };
        Pipeline::load(dir.path(), &f, &opts)
    }

    const OK: &str = "stages:\n  b:\n    cmd: [x]\n    inputs: {up: a}\n    matrix: {k: [1, two]}\n    params: {rate: 0.5, n: 3, s: hi}\n  a:\n    cmd: [x]\n    shards: 2\n";

    #[test]
    fn orders_expands_and_overrides() {
        let p = load(OK, &["b.rate=2", "b.s=42"]).unwrap();
        let names: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        let b = &p.stages[1];
        let ex: Vec<&str> = b.expansions.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(ex, ["b[k=1]", "b[k=two]"]);
        // An integer given for a float parameter becomes a float; strings stay text.
        assert_eq!(
            serde_json::to_string(&b.expansions[0].params).unwrap(),
            r#"{"k":1,"n":3,"rate":2.0,"s":"42"}"#
        );
        assert_eq!(p.stages[0].shards, 2);
    }

    /// A matrix value that is a mapping with a `name` (a declared study) names its unit by
    /// it and carries the whole mapping as the parameter; two values with one name are
    /// refused at the matrix's line.
    #[test]
    fn mapping_matrix_values_are_named_by_their_name() {
        let text = "stages:\n  s:\n    cmd: [x]\n    matrix:\n      study:\n        - {name: mc, n: 10}\n        - {name: sobol, n: 64}\n";
        let p = load(text, &[]).unwrap();
        let ex: Vec<&str> = p.stages[0]
            .expansions
            .iter()
            .map(|e| e.name.as_str())
            .collect();
        assert_eq!(ex, ["s[study=mc]", "s[study=sobol]"]);
        assert_eq!(
            serde_json::to_string(&p.stages[0].expansions[1].params).unwrap(),
            r#"{"study":{"n":64,"name":"sobol"}}"#
        );
        let e = load(&text.replace("name: sobol", "name: mc"), &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the value `mc` twice") && e.contains(":5:"),
            "{e}"
        );
    }

    /// An input may read several stages: their units' directories follow each other, and
    /// each of them runs before the reader; an empty list, a stage named twice or an unknown
    /// one is refused at the input's line.
    #[test]
    fn an_input_reads_several_stages_in_order() {
        let text = "stages:\n  r:\n    cmd: [x]\n    inputs: {models: [b, a]}\n  a:\n    cmd: [x]\n  b:\n    cmd: [x]\n    matrix: {k: [1, 2]}\n";
        let p = load(text, &[]).unwrap();
        assert_eq!(p.stage("r").unwrap().inputs["models"], ["b", "a"]);
        let order: Vec<&str> = p.stages.iter().map(|s| s.name.as_str()).collect();
        let at = |n: &str| order.iter().position(|x| *x == n).unwrap();
        assert!(at("r") > at("a") && at("r") > at("b"), "{order:?}");
        for (bad, why) in [
            ("[]", "names no stage"),
            ("[a, a]", "names stage `a` twice"),
            ("[a, c]", "unknown stage `c`"),
        ] {
            let e = load(&text.replace("[b, a]", bad), &[])
                .unwrap_err()
                .to_string();
            assert!(e.contains(why) && e.contains(":4:"), "{bad}: {e}");
        }
    }

    #[test]
    fn bad_inputs_name_their_line() {
        let e = load(OK, &["b.n=1.5"]).unwrap_err().to_string();
        assert!(e.contains(":6:") && e.contains("integer"), "{e}");
        let e = load(OK, &["b.nope=1"]).unwrap_err().to_string();
        assert!(e.contains("no parameter `nope`"), "{e}");
        let e = load(&OK.replace("up: a", "up: c"), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains(":4:") && e.contains("unknown stage `c`"), "{e}");
        let cyc = "stages:\n  a:\n    cmd: [x]\n    inputs: {u: b}\n  b:\n    cmd: [x]\n    inputs: {u: a}\n";
        let e = load(cyc, &[]).unwrap_err().to_string();
        assert!(e.contains("cycle: a -> b -> a") && e.contains(":4:"), "{e}");
        let e = load("stages:\n  a:\n    cmd: [x]\n    shard: 2\n", &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":4:") && e.contains("unknown field `shard`"),
            "{e}"
        );
        // Duplicates are refused, located at the second occurrence.
        let e = load("stages:\n  a:\n    cmd: [x]\n  a:\n    cmd: [y]\n", &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("duplicate key `a`") && e.contains(":4:"), "{e}");
        let e = load("bin_dir: ../x\nstages: {}\n", &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":1:") && e.contains("inside the workspace"),
            "{e}"
        );
    }

    #[test]
    fn constants_reach_every_referencing_stage() {
        let text = "constants:\n  g: 9.81\nstages:\n  a:\n    cmd: [x]\n    params: {g: \"${constants.g}\", n: 1}\n  b:\n    cmd: [x]\n    inputs: {up: a}\n    params: {w: {g: \"${constants.g}\"}}\n";
        let g = |p: &Pipeline| {
            (
                p.stages[0].expansions[0].params["g"].clone(),
                p.stages[1].expansions[0].params["w"]["g"].clone(),
            )
        };
        let p = load(text, &[]).unwrap();
        assert_eq!(g(&p), (9.81.into(), 9.81.into()));
        // One override changes both stages (an integer stands for the float).
        let p = load(text, &["constants.g=10"]).unwrap();
        assert_eq!(g(&p), (10.0.into(), 10.0.into()));
        let e = load(text, &["a.g=10"]).unwrap_err().to_string();
        assert!(
            e.contains("constant `g`") && e.contains("--set constants.g="),
            "{e}"
        );
        let e = load(text, &["constants.h=1"]).unwrap_err().to_string();
        assert!(e.contains("no constant `h`") && e.contains(":1:"), "{e}");
        let e = load(text, &["constants.g=fast"]).unwrap_err().to_string();
        assert!(e.contains("wrong type for constant `g`"), "{e}");
        let e = load(&text.replace("constants.g}\", n", "constants.q}\", n"), &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("unknown constant `q`") && e.contains(":6:"),
            "{e}"
        );
    }

    /// A command argument can name a constant (a description's path), and `--set` reaches
    /// inside a mapping constant, adding keys the consumer then checks.
    #[test]
    fn constants_reach_command_arguments_and_mapping_entries() {
        let text = "constants:\n  system: systems/a.yaml\n  values: {}\nstages:\n  a:\n    cmd: [x, \"${constants.system}\", -v]\n    check: true\n    params: {values: \"${constants.values}\"}\n";
        let p = load(text, &[]).unwrap();
        assert_eq!(p.stages[0].cmd, ["x", "systems/a.yaml", "-v"]);
        assert!(p.stages[0].check);
        let p = load(
            text,
            &[
                "constants.system=systems/b.yaml",
                "constants.values.k_b=2.5e8",
                "constants.values.n=3",
            ],
        )
        .unwrap();
        assert_eq!(p.stages[0].cmd[1], "systems/b.yaml");
        assert_eq!(
            p.stages[0].expansions[0].params["values"],
            serde_json::json!({"k_b": 2.5e8, "n": 3})
        );
        let e = load(text, &["constants.system.x=1"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a mapping constant"), "{e}");
        let e = load(
            &text.replace("${constants.system}", "${constants.nope}"),
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("unknown constant `nope`") && e.contains(":6:"),
            "{e}"
        );
        let e = load(
            &text.replace("${constants.system}", "${constants.values}"),
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("string or number constant"), "{e}");
    }

    #[test]
    fn symbolic_links_out_of_the_workspace_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let ws = dir.path().join("ws");
        let outside = dir.path().join("outside");
        std::fs::create_dir_all(ws.join("real/bin")).unwrap();
        std::fs::create_dir_all(&outside).unwrap();
        let link = |target: &Path, name: &str| std::os::unix::fs::symlink(target, ws.join(name));
        link(&outside, "out").unwrap();
        link(&ws.join("real"), "in").unwrap();
        link(&dir.path().join("nowhere"), "dangling").unwrap();
        link(Path::new("real/.."), "dotdot").unwrap(); // relative, stays inside
        for inside in ["real/bin", "in/bin", "in/bin/not-built-yet", "dotdot/real"] {
            assert_eq!(escape(&ws, &ws, inside), None, "{inside}");
        }
        for bad in [
            "out",
            "out/bin",
            "out/missing/deeper",
            "dangling/x",
            "in/../out/x",
        ] {
            let why = escape(&ws, &ws, bad).unwrap_or_else(|| panic!("{bad} accepted"));
            assert!(
                why.contains("symbolic link") && why.contains("outside"),
                "{bad}: {why}"
            );
        }
        // A link that climbs out through `..` after being followed.
        link(&ws.join("real/bin"), "deep").unwrap();
        assert_eq!(escape(&ws, &ws, "deep/.."), None);
        assert!(escape(&ws, &ws, "deep/../../..").is_some());
        // The lexical check still comes first.
        let why = escape(&ws, &ws, "../outside").unwrap();
        assert!(why.contains("inside the workspace"), "{why}");
        // Through the loader: bin_dir and cmd[0] are both checked.
        let f = ws.join("p.yaml");
        std::fs::write(&f, "bin_dir: out\nstages: {}\n").unwrap();
        let e = Pipeline::load(&ws, &f, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(":1:") && e.contains("symbolic link"), "{e}");
        std::fs::write(&f, "stages:\n  a:\n    cmd: [out/stage]\n").unwrap();
        let e = Pipeline::load(&ws, &f, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(":3:") && e.contains("symbolic link"), "{e}");
    }

    #[test]
    fn paths_stay_inside() {
        let ws = Path::new("/w");
        assert!(stays_inside(ws, ws, "target/release"));
        assert!(stays_inside(ws, Path::new("/w/sub"), "../bin"));
        assert!(!stays_inside(ws, ws, "../w/bin"));
        assert!(!stays_inside(ws, ws, "/usr/bin"));
    }
}
