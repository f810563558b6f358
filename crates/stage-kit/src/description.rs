//! The system description a stage's command names, and the origin every file of a stage
//! process records.
//!
//! A stage that reads the description names its file as the first argument of its command
//! (`cmd: [simulate, "${constants.system}"]`), so the orchestrator hashes the file into the
//! stage's identity; the run's parameter overrides come from the stage's `system_values`
//! parameter. The stages after `sample-params` read the recorded description
//! (`pino_data::system::read_record`) instead of the file.

use crate::{Error, Result, StageContext};
use mbd_system::{Override, System, SystemSource};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The description's path in `args` (the process's arguments after its name): the first
/// that is not `--context FILE`.
fn description_path(args: &[String]) -> Result<PathBuf> {
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--context" {
            it.next();
            continue;
        }
        return Ok(PathBuf::from(a));
    }
    Err(Error::Description(
        "no system description: the stage's command names it, as in `cmd: [simulate, \"${constants.system}\"]` with `constants: {system: systems/vtcd.yaml}`".to_owned(),
    ))
}

/// Reads and compiles the description the stage's command names, with `values` overriding
/// its parameters; the error lists every problem with its file and line.
pub fn load_description(values: &BTreeMap<String, Override>) -> Result<(SystemSource, System)> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = description_path(&args)?;
    let source =
        SystemSource::read(&path, values.clone()).map_err(|e| Error::Description(e.to_string()))?;
    let system = source
        .compile()
        .map_err(|e| Error::Description(e.to_string()))?;
    Ok((source, system))
}

impl StageContext {
    /// Declares this stage unit (its expansion, shard and resolved parameters) as the origin
    /// of every Parquet file the process writes (`pino_data::metadata::set_origin`): the
    /// first thing a stage does with its context.
    pub fn declare_origin(&self) -> Result<()> {
        pino_data::metadata::set_origin(pino_data::metadata::Origin::stage_unit(
            &self.stage,
            self.shard.index,
            self.shard.count,
            self.raw_params(),
        ))
        .map_err(Error::from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(a: &[&str]) -> Vec<String> {
        a.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_description_is_the_first_argument_besides_the_context() {
        let p = |a: &[&str]| description_path(&args(a)).map_err(|e| e.to_string());
        assert_eq!(p(&["sys.yaml"]), Ok(PathBuf::from("sys.yaml")));
        assert_eq!(
            p(&["--context", "c.json", "sys.yaml", "x"]),
            Ok(PathBuf::from("sys.yaml"))
        );
        let e = p(&["--context", "c.json"]).unwrap_err();
        assert!(e.contains("no system description"), "{e}");
    }
}
