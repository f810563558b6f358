//! The context file: what the orchestrator tells a stage process, read with the shared
//! [`stage_protocol::Context`] and wrapped with typed accessors for stage code.

use crate::{Error, Progress, Result};
use stage_protocol::{Context, ParseError};
pub use stage_protocol::{Shard, CONTEXT_ENV, PROTOCOL_VERSION};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Everything a stage process is told by the orchestrator.
#[derive(Debug, Clone)]
pub struct StageContext {
    /// Stage name as the pipeline knows it (matrix expansions carry their values).
    pub stage: String,
    /// The directory to write outputs into (exists, empty).
    pub output: PathBuf,
    /// This process's shard.
    pub shard: Shard,
    /// A directory that survives a failed or killed attempt of this very unit (same identity)
    /// and is deleted once its output is committed: the place for resumable state such as
    /// checkpoints. `None` when the stage runs by hand without one.
    pub scratch: Option<PathBuf>,
    params: serde_json::Value,
    inputs: BTreeMap<String, Vec<PathBuf>>,
    path: PathBuf,
    check: bool,
}

impl StageContext {
    /// Loads the context from `--context FILE` on the command line, else from
    /// `PINO_STAGE_CONTEXT`.
    pub fn load() -> Result<Self> {
        let args: Vec<String> = std::env::args().collect();
        if let Some(pos) = args.iter().position(|a| a == "--context") {
            if let Some(path) = args.get(pos + 1) {
                return Self::from_file(Path::new(path));
            }
        }
        match std::env::var_os(CONTEXT_ENV) {
            Some(path) => Self::from_file(Path::new(&path)),
            None => Err(Error::NoContext),
        }
    }

    /// Reads and checks a context file.
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
            path: path.to_owned(),
            source,
        })?;
        let raw = Context::parse(&text).map_err(|e| match e {
            ParseError::Malformed(source) => Error::Malformed {
                path: path.to_owned(),
                source,
            },
            ParseError::Version { found } => Error::Protocol {
                path: path.to_owned(),
                found,
                expected: PROTOCOL_VERSION,
            },
        })?;
        Ok(Self {
            stage: raw.stage,
            output: raw.output,
            shard: raw.shard,
            scratch: raw.scratch,
            params: raw.params,
            inputs: raw.inputs,
            path: path.to_owned(),
            check: raw.check,
        })
    }

    /// Whether this process runs in check mode (`check: true` in the pipeline file): validate
    /// the parameters and any file the command names, then return without reading inputs or
    /// writing outputs; an error is the unit's refusal, shown by `pipeline run` before anything
    /// runs.
    pub fn is_check(&self) -> bool {
        self.check
    }

    /// The path of the context file this was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The raw resolved parameters.
    pub fn raw_params(&self) -> &serde_json::Value {
        &self.params
    }

    /// Deserialises the parameters into the stage's typed parameter struct. Use
    /// `#[serde(deny_unknown_fields)]` there so that a misspelt parameter is an error.
    pub fn params<T: serde::de::DeserializeOwned>(&self) -> Result<T> {
        T::deserialize(&self.params).map_err(|e| Error::Params {
            stage: self.stage.clone(),
            path: self.path.clone(),
            message: e.to_string(),
        })
    }

    /// The directories that make up input `name` (one per upstream shard or expansion).
    pub fn input_dirs(&self, name: &str) -> Result<&[PathBuf]> {
        self.inputs
            .get(name)
            .map(Vec::as_slice)
            .ok_or_else(|| Error::MissingInput {
                stage: self.stage.clone(),
                name: name.to_owned(),
                available: self.inputs.keys().cloned().collect::<Vec<_>>().join(", "),
            })
    }

    /// Every file called `file_name` in the directories of input `name`, in shard order;
    /// directories without such a file are skipped.
    pub fn input_files(&self, name: &str, file_name: &str) -> Result<Vec<PathBuf>> {
        Ok(self
            .input_dirs(name)?
            .iter()
            .map(|d| d.join(file_name))
            .filter(|p| p.is_file())
            .collect())
    }

    /// The one file called `file_name` of input `name`, for inputs that are a single artifact
    /// (not sharded, not a matrix): an error names the count found otherwise.
    pub fn single_input_file(&self, name: &str, file_name: &str) -> Result<PathBuf> {
        let mut files = self.input_files(name, file_name)?;
        if files.len() != 1 {
            return Err(Error::InputCount {
                stage: self.stage.clone(),
                name: name.to_owned(),
                file_name: file_name.to_owned(),
                found: files.len(),
            });
        }
        Ok(files.remove(0))
    }

    /// The one directory of input `name` when the pipeline wires it (an optional input that
    /// is one unit's output, such as `calibration`), `None` when it does not; an error names
    /// the count otherwise.
    pub fn optional_single_input_dir(&self, name: &str) -> Result<Option<PathBuf>> {
        if !self.inputs.contains_key(name) {
            return Ok(None);
        }
        match self.input_dirs(name)? {
            [dir] => Ok(Some(dir.clone())),
            dirs => Err(Error::InputCount {
                stage: self.stage.clone(),
                name: name.to_owned(),
                file_name: "directory (one unit's output)".into(),
                found: dirs.len(),
            }),
        }
    }

    /// Names of all inputs the pipeline wired to this stage.
    pub fn input_names(&self) -> impl Iterator<Item = &str> {
        self.inputs.keys().map(String::as_str)
    }

    /// A path inside the output directory.
    pub fn output_path(&self, file_name: &str) -> PathBuf {
        self.output.join(file_name)
    }

    /// A progress reporter for `total` units of work.
    pub fn progress(&self, total: u64) -> Progress {
        Progress::new(total)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    fn write(dir: &Path, text: &str) -> PathBuf {
        let p = dir.join("context.json");
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn reads_params_inputs_and_shard() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a");
        let b = dir.path().join("b");
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(b.join("x.parquet"), b"x").unwrap();
        let text = format!(
            r#"{{"protocol":1,"stage":"s","params":{{"seed":7}},"inputs":{{"up":["{}","{}"]}},"output":"/o","shard":{{"index":1,"count":4}}}}"#,
            a.display(),
            b.display()
        );
        let ctx = StageContext::from_file(&write(dir.path(), &text)).unwrap();
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct P {
            seed: u64,
        }
        assert_eq!(ctx.params::<P>().unwrap().seed, 7);
        assert_eq!(ctx.input_dirs("up").unwrap().len(), 2);
        assert_eq!(
            ctx.input_files("up", "x.parquet").unwrap(),
            vec![b.join("x.parquet")]
        );
        assert!(ctx.shard.owns(5) && !ctx.shard.owns(4));
        assert_eq!(
            ctx.single_input_file("up", "x.parquet").unwrap(),
            b.join("x.parquet")
        );
        let err = ctx
            .single_input_file("up", "y.parquet")
            .unwrap_err()
            .to_string();
        assert!(err.contains("exactly one y.parquet, found 0"), "{err}");
        let err = ctx.input_dirs("down").unwrap_err().to_string();
        assert!(err.contains("`down`") && err.contains("up"), "{err}");
        // An optional single input: absent is None, two directories are refused by count.
        assert_eq!(ctx.optional_single_input_dir("down").unwrap(), None);
        let err = ctx.optional_single_input_dir("up").unwrap_err().to_string();
        assert!(
            err.contains("input `up`") && err.contains("found 2"),
            "{err}"
        );
    }

    #[test]
    fn unknown_parameter_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            r#"{"protocol":1,"stage":"s","params":{"sed":7},"output":"/o"}"#,
        );
        let ctx = StageContext::from_file(&p).unwrap();
        #[derive(Debug, Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct P {
            seed: u64,
        }
        let err = ctx.params::<P>().unwrap_err().to_string();
        assert!(err.contains("unknown field `sed`"), "{err}");
        assert!(err.contains("context.json"), "{err}");
    }

    #[test]
    fn wrong_protocol_and_malformed_json_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(dir.path(), r#"{"protocol":9,"stage":"s","output":"/o"}"#);
        assert!(matches!(
            StageContext::from_file(&p),
            Err(Error::Protocol { found: 9, .. })
        ));
        let p = write(dir.path(), "{ not json");
        assert!(matches!(
            StageContext::from_file(&p),
            Err(Error::Malformed { .. })
        ));
    }
}
