//! Checks before a run: a stage declared with `check: true` is started in check mode
//! (`"check": true` in its context: no inputs, a scratch output directory) once per matrix
//! expansion about to run, before the run lock is taken or anything runs. A stage validates
//! there what it can know without its inputs (its parameters, a file its command names: a
//! system description) and exits nonzero with the reason on stderr when the unit could not run;
//! any failure stops `pipeline run` with exit status 2 and the checker's message, and nothing
//! runs. Fresh units are not checked, so a run with nothing to do stays as fast as before.
//!
//! A check may also say how much work its unit is relative to the other units of its stage
//! (`::work AMOUNT`, [`stage_protocol::work_line`]); the run starts the biggest first among
//! ready units that have no recorded duration ([`crate::run`]).
//!
//! The orchestrator stays physics-free: what a check means is the stage's business.

use crate::plan::Unit;
use crate::spec::Pipeline;
use crate::status::unit_states;
use crate::{Error, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::{Command, Stdio};

/// Lines of the checker's stderr kept in the error.
const MESSAGE_LINES: usize = 40;

/// What the checks said of each checked expansion `(stage, expansion)`: its work relative to
/// its stage's other units, when the check printed one.
pub type Work = BTreeMap<(usize, usize), f64>;

/// Runs the checks of the selected units' stages that declare one, one per expansion whose
/// units are not all fresh, in pipeline order; the work each check announced.
pub fn run_checks(p: &Pipeline, units: &[Unit]) -> Result<Work> {
    let mut work = Work::new();
    if !units.iter().any(|u| p.stages[u.stage].check) {
        return Ok(work);
    }
    let states = unit_states(p)?;
    let stale: BTreeSet<&str> = states
        .iter()
        .filter(|s| s.state != "fresh")
        .map(|s| s.key.as_str())
        .collect();
    let mut done = BTreeSet::new();
    for u in units {
        let stage = &p.stages[u.stage];
        if !stage.check || !stale.contains(u.key.as_str()) || !done.insert((u.stage, u.expansion)) {
            continue;
        }
        if let Some(amount) = check_one(p, u)? {
            work.insert((u.stage, u.expansion), amount);
        }
    }
    Ok(work)
}

/// Runs one check; the work it announced (its last `::work` line), if any.
fn check_one(p: &Pipeline, u: &Unit) -> Result<Option<f64>> {
    let stage = &p.stages[u.stage];
    let exe = p.resolve_executable(stage)?;
    let name = &stage.expansions[u.expansion].name;
    let dir = std::env::temp_dir().join(format!(
        "pino-check-{}-{}",
        std::process::id(),
        blake3::hash(name.as_bytes()).to_hex()
    ));
    let io = |e| Error::io(&dir, e);
    std::fs::create_dir_all(dir.join("out")).map_err(io)?;
    let context = stage_protocol::Context {
        protocol: stage_protocol::PROTOCOL_VERSION,
        stage: name.clone(),
        params: stage.expansions[u.expansion].params.clone(),
        inputs: Default::default(),
        output: dir.join("out"),
        scratch: None,
        shard: stage_protocol::Shard {
            index: 0,
            count: stage.shards,
        },
        check: true,
    };
    let context_path = dir.join(stage_protocol::CONTEXT_FILE);
    std::fs::write(&context_path, context.to_json()).map_err(io)?;
    let output = Command::new(&exe)
        .args(&stage.cmd[1..])
        .current_dir(&p.workspace)
        .env(stage_protocol::CONTEXT_ENV, &context_path)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| Error::io(&exe, e));
    let _ = std::fs::remove_dir_all(&dir);
    let output = output?;
    if output.status.success() {
        let stdout = String::from_utf8_lossy(&output.stdout);
        return Ok(stdout
            .lines()
            .filter_map(|l| match stage_protocol::parse_line(l) {
                stage_protocol::Line::Work(amount) => Some(amount),
                _ => None,
            })
            .next_back());
    }
    Err(Error::Check {
        unit: name.clone(),
        message: located(p, &stage.name, message(&output.stderr, &exe)),
    })
}

/// A checker's message whose first line reads `params.KEY: ...`, or `STAGE: params.KEY: ...`
/// as stage binaries print their errors (a complaint about one parameter), prefixed with that
/// parameter's `FILE:LINE` in the pipeline file.
fn located(p: &Pipeline, stage: &str, message: String) -> String {
    let first = message.lines().next().unwrap_or_default();
    let rest = first.strip_prefix("params.").or_else(|| {
        let (head, tail) = first.split_once(": ")?;
        (!head.contains(' ')).then(|| tail.strip_prefix("params."))?
    });
    let key = rest
        .and_then(|r| r.split_once(':'))
        .map(|(key, _)| key)
        .filter(|key| key.chars().all(|c| c.is_alphanumeric() || c == '_'));
    match key {
        Some(key) => format!("{}: {message}", p.param_location(stage, key)),
        None => message,
    }
}

/// The checker's own words: its stderr without the `error:` prefix stage binaries print, or
/// its exit status when it said nothing.
fn message(stderr: &[u8], exe: &Path) -> String {
    let text = String::from_utf8_lossy(stderr);
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.is_empty() {
        return format!("{} refused in check mode without a message", exe.display());
    }
    let start = lines.len().saturating_sub(MESSAGE_LINES);
    lines[start..]
        .iter()
        .map(|l| l.strip_prefix("error: ").unwrap_or(l))
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::units_of;
    use crate::spec::LoadOptions;
    use std::os::unix::fs::PermissionsExt;

    /// A fresh workspace holding the executable `stage.sh` with the text `body`.
    fn stage_script(body: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let script = dir.path().join("stage.sh");
        std::fs::write(&script, body).unwrap();
        std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
        dir
    }

    /// A check's last `::work` line is the work of its expansion; a check that prints none
    /// announces none.
    #[test]
    fn the_work_a_check_announces_is_kept_per_expansion() {
        let dir = stage_script(
            "#!/bin/sh\ncase \"$1\" in\n  big) echo '::work 1'; echo '::work 9' ;;\n  small) echo '::work 2' ;;\nesac\necho '::summary parameters valid'\n",
        );
        let text = "stages:\n  a:\n    cmd: [./stage.sh, big]\n    check: true\n  b:\n    cmd: [./stage.sh, small]\n    check: true\n  c:\n    cmd: [./stage.sh, none]\n    check: true\n";
        let f = dir.path().join("p.yaml");
        std::fs::write(&f, text).unwrap();
        let p = Pipeline::load(dir.path(), &f, &LoadOptions::default()).unwrap();
        let units: Vec<Unit> = (0..p.stages.len()).flat_map(|i| units_of(&p, i)).collect();
        let work = run_checks(&p, &units).unwrap();
        assert_eq!(
            work.into_iter().collect::<Vec<_>>(),
            [((0, 0), 9.0), ((1, 0), 2.0)]
        );
    }

    /// A check's complaint about one parameter (`STAGE: params.KEY: ...`) names the line of
    /// that parameter in the pipeline file; any other complaint is passed on as said.
    #[test]
    fn a_refused_parameter_is_located_in_the_pipeline_file() {
        let dir = stage_script(
            "#!/bin/sh\ncase \"$1\" in\n  param) echo 'error: s: params.rates: `x` is not stored' >&2 ;;\n  other) echo 'no description' >&2 ;;\nesac\nexit 1\n",
        );
        for (arg, expected) in [
            ("param", "p.yaml:7: s: params.rates: `x` is not stored"),
            ("other", "nothing was run:\nno description"),
        ] {
            let text = format!("stages:\n  s:\n    cmd: [./stage.sh, {arg}]\n    check: true\n    params:\n      seed: 1\n      rates: [x]\n");
            let f = dir.path().join("p.yaml");
            std::fs::write(&f, text).unwrap();
            let p = Pipeline::load(dir.path(), &f, &LoadOptions::default()).unwrap();
            let units: Vec<Unit> = units_of(&p, 0);
            let e = run_checks(&p, &units).unwrap_err().to_string();
            assert!(e.ends_with(expected), "{e}");
        }
    }
}
