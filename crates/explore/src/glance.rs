//! The pipeline at a glance and finding a model through the orchestrator's record.
//!
//! Both read the workspace exactly as `pipeline status` and `pipeline show` do (the same library
//! calls): the units' states with their reasons and the progress of running ones, Table 4 and
//! the plots of the latest `evaluate`, and the output directories of the model and its dataset.
//! Read-only: nothing here runs a stage or writes the store.

use crate::studies::STUDY_COMMAND;
use crate::tables::read_csv;
use orchestrator::spec::Pipeline;
use orchestrator::status::{show, unit_states};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The algorithm whose model `explore` opens by default (Table 3's PINO-MBD with direct
/// derivatives, the most accurate of the paper).
pub const DEFAULT_ALGORITHM: i64 = 5;

/// Where the model and its dataset live.
#[derive(Debug, Clone, PartialEq)]
pub struct Located {
    /// The expansion that trained it (`train[algorithm=5]`).
    pub unit: String,
    /// The model directory.
    pub model_dir: PathBuf,
    /// The dataset's files.
    pub dataset: crate::session::DatasetFiles,
    /// The model's calibration: the `calibration.json` of the stage that calibrates the
    /// trained models (`calibrate`), or why none was found.
    pub calibration: Result<PathBuf, String>,
}

fn files_named(files: &[PathBuf], name: &str) -> Vec<PathBuf> {
    files
        .iter()
        .filter(|p| p.file_name().is_some_and(|n| n == name))
        .cloned()
        .collect()
}

/// The current model of `algorithm` of pipeline `p` and its dataset: the expansion whose
/// `algorithm` parameter equals it (of the stage whose models the design studies read, when
/// several stages train it: the studies and the explorer answer alike), and the
/// `params.parquet` and `irregularity.parquet` of the stages upstream of it.
pub fn locate(p: &Pipeline, algorithm: i64) -> Result<Located, String> {
    let Some((stage, unit)) = training_unit(p, algorithm) else {
        return Err(format!(
            "{}: no stage expansion trains algorithm {algorithm}; give the model with --model DIR",
            p.file
        ));
    };
    let files: Vec<PathBuf> = show(p, &unit)
        .map_err(|e| {
            format!(
                "{}: no current model of `{unit}` ({e}); run `pipeline -f {} run` first, or give --model DIR",
                p.file, p.file
            )
        })?
        .lines()
        .map(PathBuf::from)
        .collect();
    let model_dir = files_named(&files, pino_data::artifacts::MODEL_WEIGHTS)
        .first()
        .and_then(|f| f.parent().map(Path::to_path_buf))
        .ok_or_else(|| format!("{}: `{unit}` wrote no model.safetensors", p.file))?;
    let dataset = dataset_of(p, stage);
    let calibration = calibration_of(p, &stage.name);
    Ok(Located {
        unit,
        model_dir,
        dataset,
        calibration,
    })
}

/// The current output of the pipeline's `surrogate` stage (the first stage running the
/// `surrogate` binary) and its dataset; `None` when it has no such stage, `Err` when the stage
/// has no current output.
pub fn locate_surrogate(
    p: &Pipeline,
) -> Option<Result<(PathBuf, crate::session::DatasetFiles), String>> {
    let (_, stage) = p.stages_running(SURROGATE_COMMAND).next()?;
    let found = show(p, &stage.name)
        .map_err(|e| {
            format!(
                "{}: no current surrogate of `{}` ({e}); run `pipeline -f {} run` first, or give --surrogate DIR or --model DIR",
                p.file, stage.name, p.file
            )
        })
        .and_then(|text| {
            let files: Vec<PathBuf> = text.lines().map(PathBuf::from).collect();
            files_named(&files, pino_surrogate::manifest::SURROGATE_FILE)
                .first()
                .and_then(|f| f.parent().map(Path::to_path_buf))
                .ok_or_else(|| {
                    format!(
                        "{}: `{}` wrote no {}",
                        p.file,
                        stage.name,
                        pino_surrogate::manifest::SURROGATE_FILE
                    )
                })
        });
    Some(found.map(|dir| (dir, dataset_of(p, stage))))
}

/// The stage binary that builds a surrogate.
const SURROGATE_COMMAND: &str = "surrogate";

/// The `params.parquet` and `irregularity.parquet` of the stages upstream of `stage`.
fn dataset_of(p: &Pipeline, stage: &orchestrator::spec::Stage) -> crate::session::DatasetFiles {
    // Every stage upstream, nearest first.
    let mut upstream: Vec<String> = stage.inputs.values().flatten().cloned().collect();
    let mut k = 0;
    while k < upstream.len() {
        if let Some(s) = p.stages.iter().find(|s| s.name == upstream[k]) {
            for u in s.inputs.values().flatten() {
                if !upstream.contains(u) {
                    upstream.push(u.clone());
                }
            }
        }
        k += 1;
    }
    let mut dataset = crate::session::DatasetFiles::default();
    for name in &upstream {
        let Ok(text) = show(p, name) else { continue };
        let files: Vec<PathBuf> = text.lines().map(PathBuf::from).collect();
        dataset
            .params
            .extend(files_named(&files, pino_data::artifacts::PARAMS_FILE));
        dataset
            .profiles
            .extend(files_named(&files, pino_data::artifacts::IRREGULARITY_FILE));
    }
    dataset.params.dedup();
    dataset.profiles.dedup();
    dataset
}

/// The stage and unit that train `algorithm`: of the training stage whose models answer the
/// most design studies (summed over the study stages reading it; ties in the pipeline's
/// order) when it trains it, else the first stage that does.
fn training_unit(p: &Pipeline, algorithm: i64) -> Option<(&orchestrator::spec::Stage, String)> {
    let trains = |s: &orchestrator::spec::Stage| {
        s.expansions
            .iter()
            .find(|e| e.params.get("algorithm").and_then(|v| v.as_i64()) == Some(algorithm))
            .map(|e| e.name.clone())
    };
    let mut studied: Vec<(&str, usize)> = Vec::new();
    for (_, s) in p.stages_running(STUDY_COMMAND) {
        let Some(models) = s.inputs.get(STUDY_MODELS).and_then(|m| m.first()) else {
            continue;
        };
        match studied.iter_mut().find(|(m, _)| m == models) {
            Some((_, n)) => *n += s.expansions.len(),
            None => studied.push((models, s.expansions.len())),
        }
    }
    studied.sort_by_key(|&(_, n)| std::cmp::Reverse(n));
    studied
        .iter()
        .filter_map(|(m, _)| p.stage(m))
        .chain(&p.stages)
        .find_map(|s| Some((s, trains(s)?)))
}

/// The stage that calibrates the models of the training stage `train`: a stage running the
/// `calibrate` binary when one reads them, else any stage reading them whose output holds a
/// `calibration.json`. Its current output directory: the model's own file is found in it by
/// the model's identity.
fn calibration_of(p: &Pipeline, train: &str) -> Result<PathBuf, String> {
    let mut readers: Vec<&orchestrator::spec::Stage> = p
        .stages
        .iter()
        .filter(|s| s.inputs.values().flatten().any(|u| u == train))
        .collect();
    readers.sort_by_key(|s| !s.runs(CALIBRATE_COMMAND));
    let mut why = format!(
        "no error bar: {} has no stage that calibrates the models of `{train}` (a `{CALIBRATE_COMMAND}` stage)",
        p.file
    );
    for s in readers {
        let files: Vec<PathBuf> = match show(p, &s.name) {
            Ok(text) => text.lines().map(PathBuf::from).collect(),
            Err(e) => {
                if s.runs(CALIBRATE_COMMAND) {
                    why = format!(
                        "no error bar: `{}` of {} has no current output ({e}); run `pipeline -f {} run {}`",
                        s.name, p.file, p.file, s.name
                    );
                }
                continue;
            }
        };
        let found = files_named(&files, pino_calibration::CALIBRATION_FILE);
        // The model's own file is found in the output directory by its identity.
        if let Some(dir) = found.first().and_then(|f| f.parent()?.parent()) {
            return Ok(dir.to_path_buf());
        }
        if s.runs(CALIBRATE_COMMAND) {
            why = format!(
                "no error bar: `{}` of {} wrote no {}",
                s.name,
                p.file,
                pino_calibration::CALIBRATION_FILE
            );
        }
    }
    Err(why)
}

/// The stage binary that calibrates the models.
const CALIBRATE_COMMAND: &str = "calibrate";

/// A study stage's input naming the training stage whose models answer.
const STUDY_MODELS: &str = "models";

/// A unit as the page shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UnitView {
    /// Unit key.
    pub key: String,
    /// Its stage.
    pub stage: String,
    /// `fresh`, `stale`, `never run`, `submitted` or `running`.
    pub state: String,
    /// Why (stale), the job (submitted), or the progress text.
    pub detail: String,
    /// Progress of a running unit.
    pub progress: Option<Progress>,
}

/// Progress of a running unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Progress {
    /// Steps done.
    pub done: u64,
    /// Steps in all (0: not known yet).
    pub total: u64,
    /// The stage's message.
    pub message: String,
}

/// The latest evaluation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evaluation {
    /// Table 4, the header first.
    pub table4: Option<Vec<Vec<String>>>,
    /// Plot file names.
    pub plots: Vec<String>,
}

/// The page's data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Glance {
    /// The pipeline file.
    pub file: String,
    /// Every unit in pipeline order.
    pub units: Vec<UnitView>,
    /// The latest `evaluate`, when it has run.
    pub evaluate: Option<Evaluation>,
}

/// The evaluate stage of `p` (the one named `evaluate`).
const EVALUATE: &str = "evaluate";

fn evaluate_files(p: &Pipeline) -> Option<Vec<PathBuf>> {
    p.index(EVALUATE)?;
    show(p, EVALUATE)
        .ok()
        .map(|t| t.lines().map(PathBuf::from).collect())
}

/// The pipeline at a glance.
pub fn glance(p: &Pipeline) -> Result<Glance, String> {
    let units = unit_states(p)
        .map_err(|e| e.to_string())?
        .into_iter()
        .map(|u| UnitView {
            stage: p.stages[u.stage].name.clone(),
            progress: u.progress.map(|g| Progress {
                done: g.done,
                total: g.total,
                message: g.message,
            }),
            key: u.key,
            state: u.state.to_owned(),
            detail: u.detail,
        })
        .collect();
    let evaluate = evaluate_files(p).map(|files| Evaluation {
        table4: files_named(&files, "table4.csv")
            .first()
            .and_then(|f| read_csv(f).ok()),
        plots: plot_names(&files),
    });
    Ok(Glance {
        file: p.file.clone(),
        units,
        evaluate,
    })
}

fn plot_names(files: &[PathBuf]) -> Vec<String> {
    files
        .iter()
        .filter(|f| f.extension().is_some_and(|e| e == "png"))
        .filter_map(|f| f.file_name()?.to_str().map(str::to_owned))
        .collect()
}

/// The path of the latest evaluation's plot `name` (only names the evaluation lists).
pub fn plot_path(p: &Pipeline, name: &str) -> Option<PathBuf> {
    evaluate_files(p)?
        .into_iter()
        .filter(|f| f.extension().is_some_and(|e| e == "png"))
        .find(|f| f.file_name().is_some_and(|n| n == name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use orchestrator::spec::LoadOptions;

    fn pipeline(text: &str) -> Pipeline {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.yaml");
        std::fs::write(&f, text).unwrap();
        Pipeline::load(dir.path(), &f, &LoadOptions::default()).unwrap()
    }

    const TRAINS: &str = "\
stages:
  train:
    cmd: [train]
    matrix: {algorithm: [1, 5]}
  train-rates:
    extends: train
    params: {algorithm: 5, rate_outputs: [z_a]}
";

    #[test]
    fn the_model_opened_is_the_one_the_studies_read() {
        let unit = |p: &Pipeline, a| training_unit(p, a).map(|(s, u)| (s.name.clone(), u));
        // No studies: the first stage that trains it.
        let p = pipeline(TRAINS);
        assert_eq!(
            unit(&p, 5),
            Some(("train".into(), "train[algorithm=5]".into()))
        );
        // The studies read `train-rates`: so does the explorer, for the algorithm it trains.
        let studied = format!(
            "{TRAINS}  study:\n    cmd: [study]\n    inputs: {{models: train-rates}}\n    params: {{algorithm: 5}}\n"
        );
        let p = pipeline(&studied);
        assert_eq!(
            unit(&p, 5),
            Some(("train-rates".into(), "train-rates".into()))
        );
        assert_eq!(
            unit(&p, 1),
            Some(("train".into(), "train[algorithm=1]".into()))
        );
        assert_eq!(unit(&p, 3), None);
        // Two study stages (found by their command, whatever their names): the model answering
        // more studies wins, whichever stage comes first.
        let split = format!(
            "{TRAINS}  a-study:\n    cmd: [./bin/study]\n    inputs: {{models: train}}\n    matrix: {{study: [{{name: one}}]}}\n  b-study:\n    cmd: [study]\n    inputs: {{models: train-rates}}\n    matrix: {{study: [{{name: two}}, {{name: three}}]}}\n"
        );
        let p = pipeline(&split);
        assert_eq!(
            unit(&p, 5),
            Some(("train-rates".into(), "train-rates".into()))
        );
        let p = pipeline(&split.replace("{name: two}, ", ""));
        assert_eq!(
            unit(&p, 5),
            Some(("train".into(), "train[algorithm=5]".into())),
            "a tie: the first study stage's"
        );
    }
}
