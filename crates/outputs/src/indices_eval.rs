//! The engineering indices of the surrogate against the solver, for `evaluate`: the indices
//! the system description defines (its `railway:` family and its own `indices:`, crate
//! `pino-indices`, `docs/indices.md`), through the same [`pino_indices::IndexSet`] as the
//! `indices` stage.
//!
//! Per scored sample and model, each column an index reads is rebuilt from the prediction
//! ([`IndexInputs`]): an output the model predicts is taken as predicted (displacements,
//! contact and element forces); a rigid DOF's velocity or acceleration, and a sensor's, are
//! central differences of the predicted displacement; an element's deflection is its
//! kinematics over the predicted displacements and the exact profile; a profile is the exact
//! input. Central differences exist on the interior points `1..T-1` of the window, so both
//! sides use those points (from the description's `indices_from` on, as the `indices` stage:
//! [`IndexConfig::first_at`]); the exact side reads the solver's values (its exact `_v` / `_a`,
//! and the stored column for anything the model does not carry). The truth row
//! (algorithm 0) takes the exact displacements through the same reconstruction: the floor of
//! every model. A column the prediction cannot give (a stored force of an element the model
//! does not predict, ...) is named in the report and the indices are left out.
//!
//! Written: `indices_errors.{parquet,csv,md}` (per index and algorithm: mean and worst absolute
//! error and the worst sample, mean and worst relative error (%), Pearson correlation),
//! `indices_samples.parquet` (per algorithm and sample: predicted and exact) and
//! `indices_scatter_<index>.png`.

use crate::physical::{exact_physical, to_physical, Physical};
use crate::Result;
use atomic_file::write_atomic;
use mbd_system::system::Quantity;
use mbd_system::System;
use pino_data::{schema, write_parquet, Column, Table};
use pino_indices::system::IndexInfo;
use pino_indices::{IndexConfig, IndexParams, IndexSet};
use pino_learn::checkpoint::{ModelMeta, TimeGrid};
use pino_learn::config::WindowConfig;
use pino_learn::data::{Prepared, Split};
use pino_learn::layout::Layout;
use pino_learn::residual::ChannelMap;
use pino_learn::Error as LearnError;
use report::csv::write_csv;
use report::plot::{write_png, Figure, Panel, Series, BLACK, PALETTE, RED};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Where one index input comes from on the prediction's side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// An output the model predicts (its channel).
    Output(usize),
    /// Rigid DOF `i`'s velocity (1) or acceleration (2): central differences of the
    /// prediction; exact: the solver's `_v` / `_a`.
    DofRate(usize, u8),
    /// The velocity (1) or acceleration (2) of a predicted displacement output (a sensor):
    /// central differences; exact: the stored column.
    OutputRate(usize, u8),
    /// An excitation input (exact on both sides).
    Excitation(usize),
    /// Element `e`'s deflection over the predicted displacements and the exact profile;
    /// exact: the stored column.
    Deflection(usize),
}

impl Source {
    /// Whether the exact side is a stored column `evaluate` reads beside the model's data.
    fn exact_is_stored(self) -> bool {
        matches!(self, Source::OutputRate(..) | Source::Deflection(_))
    }
}

/// The index columns of a system and how each is rebuilt from a model's prediction.
#[derive(Debug, Clone)]
pub struct IndexInputs {
    set: IndexSet,
    columns: Vec<IndexInfo>,
    sources: Vec<(String, Source)>,
    /// Input columns no prediction of this layout can give, with the reason.
    underivable: Vec<(String, String)>,
}

impl IndexInputs {
    /// The indices of `system` and their inputs for a model of `layout`.
    pub fn of(system: &System, layout: &Layout) -> Result<Self> {
        let set = IndexSet::of(system);
        let map = ChannelMap::new(system, layout);
        let nominal =
            pino_learn::residual::sample_equations(system, &system.nominal(), Vec::new())?;
        let output = |name: &str| layout.outputs.iter().position(|o| o == name);
        let mut sources = Vec::new();
        let mut underivable = Vec::new();
        for name in set.inputs() {
            let Some(ch) = system.channel(&name) else {
                underivable.push((name, "not a column of the description".into()));
                continue;
            };
            let source = if let Some(c) = output(&name) {
                Some(Source::Output(c))
            } else {
                match system.channels[ch].quantity {
                    Quantity::Dof(i, order) if order > 0 => Some(Source::DofRate(i, order)),
                    Quantity::Sensor(s, order) if order > 0 => system
                        .channels
                        .iter()
                        .find(|c| c.quantity == Quantity::Sensor(s, 0))
                        .and_then(|c| output(&c.name))
                        .map(|c| Source::OutputRate(c, order)),
                    Quantity::Excitation(_) | Quantity::ExcitationRate(_) => layout
                        .excitations
                        .iter()
                        .position(|x| *x == name)
                        .map(Source::Excitation),
                    Quantity::Deflection(e) => {
                        map.deflection(&nominal, e).map(|_| Source::Deflection(e))
                    }
                    _ => None,
                }
            };
            match source {
                Some(s) => sources.push((name, s)),
                None => underivable.push((
                    name,
                    "neither predicted by the model nor derivable from its outputs".into(),
                )),
            }
        }
        Ok(Self {
            columns: set.columns(system),
            set,
            sources,
            underivable,
        })
    }

    /// The index columns, in value order.
    pub fn columns(&self) -> &[IndexInfo] {
        &self.columns
    }

    /// Every column the indices read, with where a prediction's value comes from (the
    /// description's index set's input order).
    pub fn sources(&self) -> &[(String, Source)] {
        &self.sources
    }

    /// The description's index set.
    pub fn set(&self) -> &IndexSet {
        &self.set
    }

    /// The limit of each index column (`None`: none); a value passes at or below it.
    pub fn limits(&self, system: &System, cfg: &IndexConfig) -> Vec<Option<f64>> {
        self.set.column_limits(system, cfg)
    }

    /// The limits `values` (in [`IndexInputs::columns`] order) exceed, named as the `indices`
    /// stage names them ([`pino_indices::IndexSet::failed`]): the railway family's limits by the
    /// limit's name (the Sperling limit once, judged on the largest of its points), each simple
    /// index by its own. What a surrogate judges on values assembled from several models.
    pub fn failed_of(&self, system: &System, values: &[f64], cfg: &IndexConfig) -> Vec<String> {
        const SPERLING: &str = "sperling_wz";
        let railway = self.set.railway.is_some();
        let mut out: Vec<String> = Vec::new();
        let mut sperling = f64::NEG_INFINITY;
        let mut sperling_limit = None;
        for ((c, &v), limit) in self
            .columns
            .iter()
            .zip(values)
            .zip(self.limits(system, cfg))
        {
            let Some(limit) = limit else { continue };
            if railway
                && c.name.starts_with(SPERLING)
                && pino_indices::INDEX_COLUMNS.iter().any(|r| r.name == c.name)
            {
                sperling = sperling.max(v);
                sperling_limit = Some(limit);
            } else if v > limit || v.is_nan() {
                out.push(c.name.clone());
            }
        }
        if let Some(limit) = sperling_limit {
            if sperling > limit || sperling.is_nan() {
                let at = out
                    .iter()
                    .position(|n| !pino_indices::INDEX_COLUMNS.iter().any(|c| c.name == n))
                    .unwrap_or(out.len());
                out.insert(at, SPERLING.into());
            }
        }
        out
    }

    /// Whether every index can be computed from a prediction (and there is one).
    pub fn computable(&self) -> bool {
        !self.set.is_empty() && self.underivable.is_empty()
    }

    /// Why the indices cannot be computed from a prediction (empty when they can).
    pub fn why_not(&self) -> String {
        if self.set.is_empty() {
            return "the description defines no index (`indices:`, `railway:`)".into();
        }
        self.underivable
            .iter()
            .map(|(name, why)| format!("`{name}`: {why}"))
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// Stored columns the exact side reads beside the model's data.
    pub fn stored_columns(&self) -> Vec<&str> {
        self.sources
            .iter()
            .filter(|(_, s)| s.exact_is_stored())
            .map(|(n, _)| n.as_str())
            .collect()
    }

    /// How each input is taken from the prediction, for the report.
    fn describe(&self, layout: &Layout) -> Vec<String> {
        let rate = |o: u8| if o == 1 { "velocity" } else { "acceleration" };
        self.sources
            .iter()
            .map(|(name, s)| {
                let how = match *s {
                    Source::Output(_) => "predicted".to_owned(),
                    Source::DofRate(i, o) | Source::OutputRate(i, o) => format!(
                        "{} by central differences of the predicted `{}`",
                        rate(o),
                        layout.outputs[i]
                    ),
                    Source::Excitation(_) => "the exact input".to_owned(),
                    Source::Deflection(_) => {
                        "the element's kinematics over the predicted displacements".to_owned()
                    }
                };
                format!("`{name}`: {how}")
            })
            .collect()
    }
}

/// The stored columns [`IndexInputs::stored_columns`] of the scored samples over a model's
/// window, by sample id.
#[derive(Debug, Clone, Default)]
pub struct StoredColumns {
    columns: Vec<String>,
    by_id: BTreeMap<i64, Vec<Vec<f64>>>,
}

impl StoredColumns {
    /// Reads `inputs`' stored columns of samples `ids` from `files`, each cut to `window`.
    pub fn read(
        files: &[PathBuf],
        inputs: &IndexInputs,
        ids: &BTreeSet<i64>,
        window: &WindowConfig,
    ) -> Result<Self> {
        let columns: Vec<&str> = inputs.stored_columns();
        let mut by_id = BTreeMap::new();
        if !columns.is_empty() {
            pino_data::records::for_each_record(files, &columns, &mut |_, rec| {
                if ids.contains(&rec.id) {
                    let n = rec.columns.first().map_or(0, Vec::len);
                    let cut = rec
                        .columns
                        .iter()
                        .map(|c| window.rows(n).map(|k| c[k]).collect())
                        .collect();
                    by_id.insert(rec.id, cut);
                }
                Ok::<(), LearnError>(())
            })?;
        }
        Ok(Self {
            columns: columns.into_iter().map(str::to_owned).collect(),
            by_id,
        })
    }

    /// The stored columns of one sample already cut to the model's window (a solve made
    /// outside a dataset): `values[c]` is the series of `inputs`' stored column `c`.
    pub fn of_sample(inputs: &IndexInputs, id: i64, values: Vec<Vec<f64>>) -> Self {
        Self {
            columns: inputs
                .stored_columns()
                .into_iter()
                .map(str::to_owned)
                .collect(),
            by_id: BTreeMap::from([(id, values)]),
        }
    }

    fn get(&self, id: i64, name: &str) -> Option<&[f64]> {
        let c = self.columns.iter().position(|x| x == name)?;
        Some(&self.by_id.get(&id)?[c])
    }
}

/// The indices of one model's predictions (or of the truth row) on the scored samples.
#[derive(Debug, Clone)]
pub struct ModelIndices {
    /// Algorithm id (0: the truth row).
    pub algorithm: i64,
    /// Label for tables and plots.
    pub label: String,
    /// Scored sample ids.
    pub ids: Vec<i64>,
    /// Index values of the prediction, per sample ([`IndexInputs::columns`] order).
    pub predicted: Vec<Vec<f64>>,
    /// Index values of the solver's solution, per sample.
    pub exact: Vec<Vec<f64>>,
    /// The rates the model outputs directly, which its indices read instead of differences.
    pub direct: Vec<String>,
}

/// The settings `evaluate` uses for the indices of `system`: the stage's defaults with no
/// start-up fraction (the model's window already dropped it), from the description's
/// `indices_from` on.
pub fn eval_config(system: &System) -> Result<IndexConfig> {
    let params = IndexParams {
        window_start_fraction: 0.0,
        ..IndexParams::default()
    };
    let cfg = params.validate().map_err(|e| LearnError::OutOfRange {
        field: "indices".into(),
        value: e.to_string(),
        allowed: "valid index parameters".into(),
    })?;
    Ok(cfg.of_system(system))
}

/// The index inputs of one side of one sample, on the interior points `1..T-1` the indices
/// read ([`IndexConfig::first_at`]).
struct SampleColumns(BTreeMap<String, Vec<f64>>);

/// Rebuilds the inputs from a prediction (`exact: None`) or reads the solver's values
/// (`exact: Some(stored)`, the stored columns of sample `id`) of one sample with parameters
/// `params`, physical series `side` and excitations `eta [T, E]` at spacing `dt`, on the
/// interior points from `first` on (at least 1).
#[allow(clippy::too_many_arguments)]
fn sample_columns(
    system: &System,
    inputs: &IndexInputs,
    params: &[f64],
    id: i64,
    side: &Physical,
    exact: Option<&StoredColumns>,
    eta: &[f64],
    layout: &Layout,
    dt: f64,
    first: usize,
) -> Result<SampleColumns> {
    let (o, d, e) = (layout.n_outputs(), layout.n_dofs(), layout.n_excitations());
    let t = eta.len() / e.max(1);
    let t = if e == 0 { side.u.len() / o } else { t };
    let interior = first.max(1)..t.saturating_sub(1);
    if interior.is_empty() && first > 1 {
        return Err(LearnError::Dataset {
            path: PathBuf::from(system.name.clone()),
            message: format!(
                "sample {id}: the description's `indices_from` leaves no point of the {t}-point \
                 window, which ends before it: the indices need a longer run (or an earlier \
                 `indices_from`)"
            ),
        }
        .into());
    }
    let map = ChannelMap::new(system, layout);
    let mut equations = None;
    let mut out = BTreeMap::new();
    for (name, source) in &inputs.sources {
        let u = |c: usize| -> Vec<f64> { interior.clone().map(|r| side.u[r * o + c]).collect() };
        let values: Vec<f64> = if let Some(stored) = exact.filter(|_| source.exact_is_stored()) {
            let col = stored.get(id, name).ok_or_else(|| LearnError::Dataset {
                path: PathBuf::from("evaluate"),
                message: format!("sample {id}: stored column `{name}` not read"),
            })?;
            interior.clone().map(|r| col[r]).collect()
        } else {
            match *source {
                Source::Output(c) => u(c),
                Source::Excitation(j) => interior.clone().map(|r| eta[r * e + j]).collect(),
                Source::DofRate(j, order) => {
                    let x = if order == 1 { &side.v } else { &side.a };
                    if exact.is_some() {
                        // The solver's rates, stored at every window point.
                        interior.clone().map(|r| x[r * d + j]).collect()
                    } else {
                        // Central differences, at the interior points only (row r - 1).
                        interior.clone().map(|r| x[(r - 1) * d + j]).collect()
                    }
                }
                Source::OutputRate(c, order) => interior
                    .clone()
                    .map(|r| {
                        let at = |k: usize| side.u[k * o + c];
                        let (p, m, n) = (at(r - 1), at(r), at(r + 1));
                        if order == 1 {
                            (n - p) / (2.0 * dt)
                        } else {
                            (n - 2.0 * m + p) / (dt * dt)
                        }
                    })
                    .collect(),
                Source::Deflection(el) => {
                    let eq = match &equations {
                        Some(eq) => eq,
                        None => equations.insert(pino_learn::residual::sample_equations(
                            system,
                            &system.sampled_values(params)?,
                            Vec::new(),
                        )?),
                    };
                    let Some(reader) = map.deflection(eq, el) else {
                        return Err(LearnError::Dataset {
                            path: PathBuf::from("evaluate"),
                            message: format!("`{name}`: not derivable from the outputs"),
                        }
                        .into());
                    };
                    interior
                        .clone()
                        .map(|r| reader.at(&side.u[r * o..(r + 1) * o], &eta[r * e..(r + 1) * e]))
                        .collect()
                }
            }
        };
        out.insert(name.clone(), values);
    }
    Ok(SampleColumns(out))
}

/// The index values of one sample, from a prediction or (with `exact`) the solver.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleIndices {
    /// Values in [`IndexInputs::columns`] order.
    pub values: Vec<f64>,
    /// Length of the window they were taken over (s).
    pub window_s: f64,
    /// The indices over their limits.
    pub failed: Vec<String>,
}

impl IndexInputs {
    /// The indices of one sample (`params` its sampled parameters, `id` for messages) from
    /// its physical series `side` and excitations `eta [T, E]` on the window `grid`, from
    /// `cfg`'s time on ([`IndexConfig::first_at`]): rebuilt from a
    /// prediction (`exact: None`, [`to_physical`]'s interior derivatives) or the solver's
    /// values (`exact: Some`, [`exact_physical`]'s and the stored columns).
    #[allow(clippy::too_many_arguments)]
    pub fn sample(
        &self,
        system: &System,
        layout: &Layout,
        params: &[f64],
        id: i64,
        side: &Physical,
        exact: Option<&StoredColumns>,
        eta: &[f64],
        grid: &TimeGrid,
        cfg: &IndexConfig,
    ) -> Result<SampleIndices> {
        let dt = grid.dt;
        let first = cfg.first_at(grid.t0, dt);
        let cols = sample_columns(
            system, self, params, id, side, exact, eta, layout, dt, first,
        )?;
        let points = cols.0.values().next().map_or(0, Vec::len);
        let get = |name: &str| cols.0.get(name).cloned();
        let values = system.values(&system.sampled_values(params)?)?;
        let (v, railway) = self
            .set
            .compute(system, &values, &get, dt, cfg)
            .map_err(|e| LearnError::Dataset {
                path: PathBuf::from(if exact.is_some() {
                    "solver"
                } else {
                    "prediction"
                }),
                message: format!("sample {id}: indices: {e}"),
            })?;
        let failed = self.set.failed(system, &v, railway.as_ref(), cfg);
        Ok(SampleIndices {
            window_s: railway.map_or(points as f64 * dt, |r| r.window_s),
            values: v,
            failed,
        })
    }
}

/// The indices of one model's predictions `preds` (physical, in `idx` order) and of the
/// exact solutions of samples `idx` (with their `stored` columns).
pub fn model_indices(
    system: &System,
    inputs: &IndexInputs,
    items: &Prepared,
    idx: &[usize],
    preds: &[Physical],
    stored: &StoredColumns,
    meta: &ModelMeta,
) -> Result<ModelIndices> {
    let cfg = eval_config(system)?;
    let layout = &meta.layout;
    let mut out = ModelIndices {
        algorithm: meta.train.algorithm.id(),
        label: alg_label(meta),
        ids: Vec::with_capacity(idx.len()),
        predicted: Vec::with_capacity(idx.len()),
        exact: Vec::with_capacity(idx.len()),
        direct: layout.rate_outputs().to_vec(),
    };
    for (k, &i) in idx.iter().enumerate() {
        let (ex, eta) = exact_physical(items, i, &meta.norm)?;
        let (params, id) = (items.params(i), items.id(i));
        let side = |phys: &Physical, exact: Option<&StoredColumns>| {
            inputs.sample(
                system, layout, params, id, phys, exact, &eta, &meta.grid, &cfg,
            )
        };
        out.exact.push(side(&ex, Some(stored))?.values);
        out.predicted.push(side(&preds[k], None)?.values);
        out.ids.push(id);
    }
    Ok(out)
}

/// The truth row: the exact displacements and forces through the model's reconstruction
/// (z-score of the exact outputs, then [`to_physical`]).
pub fn truth_indices(
    system: &System,
    inputs: &IndexInputs,
    items: &Prepared,
    idx: &[usize],
    stored: &StoredColumns,
    meta: &ModelMeta,
) -> Result<ModelIndices> {
    let mut preds = Vec::with_capacity(idx.len());
    for &i in idx {
        let s = items.series(i)?;
        preds.push(to_physical(&s.u, meta));
    }
    let mut m = model_indices(system, inputs, items, idx, &preds, stored, meta)?;
    m.algorithm = 0;
    m.label = "truth: exact, central differences".into();
    m.direct.clear();
    Ok(m)
}

/// Error statistics of one index for one model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexError {
    /// Mean of `|pred - exact|` (index unit).
    pub mean_abs: f64,
    /// Largest `|pred - exact|`.
    pub worst_abs: f64,
    /// Sample of the largest absolute error.
    pub worst_abs_sample: i64,
    /// Mean of `|pred - exact| / |exact|` (%), over samples with `exact != 0`.
    pub mean_rel_pct: f64,
    /// Largest relative error (%).
    pub worst_rel_pct: f64,
    /// Pearson correlation of predicted and exact over the samples (NaN when either is
    /// constant).
    pub correlation: f64,
    /// Mean of the exact values (for scale).
    pub exact_mean: f64,
}

/// Statistics of `pred` against `exact` (same samples, ids `ids`).
pub fn index_error(pred: &[f64], exact: &[f64], ids: &[i64]) -> IndexError {
    let n = pred.len().max(1) as f64;
    let abs: Vec<f64> = pred.iter().zip(exact).map(|(p, e)| (p - e).abs()).collect();
    let (wa, wa_v) = abs
        .iter()
        .enumerate()
        .fold((0usize, f64::NEG_INFINITY), |b, (i, &v)| {
            if v > b.1 {
                (i, v)
            } else {
                b
            }
        });
    let rels: Vec<f64> = abs
        .iter()
        .zip(exact)
        .filter(|(_, e)| **e != 0.0)
        .map(|(a, e)| 100.0 * a / e.abs())
        .collect();
    let mp = pred.iter().sum::<f64>() / n;
    let me = exact.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (p, e) in pred.iter().zip(exact) {
        sxy += (p - mp) * (e - me);
        sxx += (p - mp) * (p - mp);
        syy += (e - me) * (e - me);
    }
    IndexError {
        mean_abs: abs.iter().sum::<f64>() / n,
        worst_abs: wa_v.max(0.0),
        worst_abs_sample: ids.get(wa).copied().unwrap_or(-1),
        mean_rel_pct: rels.iter().sum::<f64>() / rels.len().max(1) as f64,
        worst_rel_pct: rels.iter().copied().fold(0.0, f64::max),
        correlation: if sxx > 0.0 && syy > 0.0 {
            sxy / (sxx * syy).sqrt()
        } else {
            f64::NAN
        },
        exact_mean: me,
    }
}

/// Writes the index files (module doc) for `models` (the truth row first, then by algorithm)
/// scored on `split`; when the indices cannot be computed from the predictions
/// ([`IndexInputs::computable`]), `indices_errors.md` alone says why.
pub fn write_indices(
    out: &Path,
    split: Split,
    inputs: &IndexInputs,
    layout: &Layout,
    models: &[ModelIndices],
) -> Result<()> {
    if !inputs.computable() {
        return Ok(write_atomic(
            &out.join("indices_errors.md"),
            not_computed(inputs).as_bytes(),
        )?);
    }
    let columns = inputs.columns();
    let stats = write_errors_table(out, split, inputs, models)?;
    let md = errors_markdown(split, inputs, layout, models, &stats);
    write_atomic(&out.join("indices_errors.md"), md.as_bytes())?;
    write_samples_table(out, inputs, models)?;
    for (j, c) in columns.iter().enumerate() {
        scatter(
            &out.join(format!("indices_scatter_{}.png", c.name)),
            j,
            c,
            models,
        )?;
    }
    Ok(())
}

/// `indices_errors.md` when the indices cannot be computed: why.
fn not_computed(inputs: &IndexInputs) -> String {
    let mut md = String::from(
        "# Engineering indices: surrogate against solver

",
    );
    if inputs.set.is_empty() {
        md.push_str("The system description defines no index (`indices:`, `railway:`).\n");
    } else {
        md.push_str(
            "Not computed: the indices read columns the model's predictions cannot give.\n\n",
        );
        for (name, why) in &inputs.underivable {
            md.push_str(&format!("- `{name}`: {why}\n"));
        }
        md.push_str(
            "\nList the columns (or the displacements they follow from) among the \
                 description's `outputs:` and retrain to score them.\n",
        );
    }
    md
}

/// `indices_errors.parquet` and `.csv`: one row per (algorithm, index); the rows' errors, in
/// that order.
fn write_errors_table(
    out: &Path,
    split: Split,
    inputs: &IndexInputs,
    models: &[ModelIndices],
) -> Result<Vec<IndexError>> {
    let columns = inputs.columns();
    let value = |rows: &[Vec<f64>], s: usize, k: usize| rows[s][k];
    // Errors table: one row per (algorithm, index).
    let (mut alg, mut name, mut unit) = (Vec::new(), Vec::new(), Vec::new());
    let mut stats: Vec<IndexError> = Vec::new();
    for m in models {
        for (k, c) in columns.iter().enumerate() {
            let p: Vec<f64> = (0..m.ids.len())
                .map(|s| value(&m.predicted, s, k))
                .collect();
            let e: Vec<f64> = (0..m.ids.len()).map(|s| value(&m.exact, s, k)).collect();
            alg.push(m.algorithm);
            name.push(c.name.clone());
            unit.push(c.unit.clone());
            stats.push(index_error(&p, &e, &m.ids));
        }
    }
    let mut t = Table::default();
    t.push("algorithm", Column::I64(alg.clone()))?;
    t.push("index", Column::Str(name.clone()))?;
    t.push("unit", Column::Str(unit.clone()))?;
    t.push(
        "split",
        Column::Str(alg.iter().map(|_| split.as_str().to_owned()).collect()),
    )?;
    let f = |g: &dyn Fn(&IndexError) -> f64| Column::F64(stats.iter().map(g).collect());
    t.push("exact_mean", f(&|s| s.exact_mean))?;
    t.push("mean_abs_error", f(&|s| s.mean_abs))?;
    t.push("worst_abs_error", f(&|s| s.worst_abs))?;
    t.push(
        "worst_abs_sample_id",
        Column::I64(stats.iter().map(|s| s.worst_abs_sample).collect()),
    )?;
    t.push("mean_rel_error_pct", f(&|s| s.mean_rel_pct))?;
    t.push("worst_rel_error_pct", f(&|s| s.worst_rel_pct))?;
    t.push("correlation", f(&|s| s.correlation))?;
    write_parquet(&out.join("indices_errors.parquet"), &t)?;
    write_csv(&out.join("indices_errors.csv"), &t)?;
    Ok(stats)
}

/// `indices_errors.md`: the errors' table for people, index by algorithm.
fn errors_markdown(
    split: Split,
    inputs: &IndexInputs,
    layout: &Layout,
    models: &[ModelIndices],
    stats: &[IndexError],
) -> String {
    let columns = inputs.columns();
    let n = models.first().map_or(0, |m| m.ids.len());
    let mut md = format!(
        "# Engineering indices: surrogate against solver on the {} split ({n} samples)\n\n\
         Definitions: docs/indices.md and the system description. The columns the indices read, \
         from the prediction: {}. Central differences exist on the interior points of the \
         window, so both sides are taken there (the exact side with the solver's values). \
         Algorithm 0 is the truth row: the exact displacements through the same reconstruction \
         (the floor of every model).\n\n\
         | index | unit | exact mean |",
        split.as_str(),
        inputs.describe(layout).join("; ")
    );
    for m in models.iter().filter(|m| !m.direct.is_empty()) {
        md.insert_str(
            md.find("\n\n|").unwrap_or(md.len()),
            &format!(
                " Algorithm {} reads {} from its own outputs (`{}`), not from differences.",
                m.algorithm,
                m.direct
                    .iter()
                    .map(|d| format!("`{d}`"))
                    .collect::<Vec<_>>()
                    .join(", "),
                m.label
            ),
        );
    }
    for m in models {
        md.push_str(&format!(
            " alg {}: mean abs / worst abs (sample) / mean rel % / worst rel % / r |",
            m.algorithm
        ));
    }
    md.push_str("\n|---|---|---|");
    md.push_str(&"---|".repeat(models.len()));
    md.push('\n');
    let cell = |v: f64| {
        if v.is_nan() {
            "-".to_owned()
        } else {
            format!("{v:.4}")
        }
    };
    for (k, c) in columns.iter().enumerate() {
        md.push_str(&format!(
            "| `{}` | {} | {} |",
            c.name,
            c.unit,
            cell(stats.get(k).map_or(f64::NAN, |s| s.exact_mean))
        ));
        for m in 0..models.len() {
            let s = &stats[m * columns.len() + k];
            md.push_str(&format!(
                " {} / {} ({}) / {:.2} / {:.2} / {:.3} |",
                cell(s.mean_abs),
                cell(s.worst_abs),
                s.worst_abs_sample,
                s.mean_rel_pct,
                s.worst_rel_pct,
                s.correlation
            ));
        }
        md.push('\n');
    }
    md.push_str("\nScatter plots: `indices_scatter_<index>.png` (predicted against exact, one panel per algorithm, black line: equality).\n");
    md
}

/// `indices_samples.parquet`: every sample's predicted and exact index values.
fn write_samples_table(out: &Path, inputs: &IndexInputs, models: &[ModelIndices]) -> Result<()> {
    let columns = inputs.columns();
    // Every index and its exact value beside it carry the index's unit.
    let units = pino_data::units::Units::default().with(columns.iter().flat_map(|c| {
        [
            (c.name.clone(), c.unit.clone()),
            (format!("{}_exact", c.name), c.unit.clone()),
        ]
    }))?;
    let mut s = Table::default().with_units(units);
    let rows: Vec<(usize, usize)> = models
        .iter()
        .enumerate()
        .flat_map(|(m, mi)| (0..mi.ids.len()).map(move |k| (m, k)))
        .collect();
    s.push(
        "algorithm",
        Column::I64(rows.iter().map(|&(m, _)| models[m].algorithm).collect()),
    )?;
    s.push(
        schema::SAMPLE_ID,
        Column::I64(rows.iter().map(|&(m, k)| models[m].ids[k]).collect()),
    )?;
    for (j, c) in columns.iter().enumerate() {
        s.push(
            &c.name,
            Column::F64(
                rows.iter()
                    .map(|&(m, k)| models[m].predicted[k][j])
                    .collect(),
            ),
        )?;
        s.push(
            &format!("{}_exact", c.name),
            Column::F64(rows.iter().map(|&(m, k)| models[m].exact[k][j]).collect()),
        )?;
    }
    write_parquet(&out.join("indices_samples.parquet"), &s)?;
    Ok(())
}

/// One PNG per index: a panel per model, predicted (y) against exact (x), each sample a small
/// cross, the equality line in black.
fn scatter(path: &Path, j: usize, c: &IndexInfo, models: &[ModelIndices]) -> Result<()> {
    let all = models
        .iter()
        .flat_map(|m| m.predicted.iter().chain(&m.exact))
        .map(|ix| ix[j])
        .filter(|v| v.is_finite());
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let (lo, hi) = if lo < hi {
        (lo, hi)
    } else {
        (lo - 1.0, lo + 1.0)
    };
    let arm = 0.012 * (hi - lo);
    let mut panels = Vec::new();
    for mi in models {
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for (p, e) in mi.predicted.iter().zip(&mi.exact) {
            let (px, py) = (e[j], p[j]);
            // A cross: two strokes, each ended by a NaN that breaks the polyline.
            for (dx, dy) in [(arm, arm), (arm, -arm)] {
                x.extend([px - dx, px + dx, f64::NAN]);
                y.extend([py - dy, py + dy, f64::NAN]);
            }
        }
        let color = if mi.algorithm == 0 {
            RED
        } else {
            PALETTE[(mi.algorithm as usize - 1) % PALETTE.len()]
        };
        panels.push(Panel {
            title: if mi.algorithm == 0 {
                mi.label.clone()
            } else {
                format!("alg {}", mi.label)
            },
            xlabel: format!("exact {} ({}) {:.3} - {:.3}", c.name, c.unit, lo, hi),
            series: vec![
                Series {
                    x: vec![lo, hi],
                    y: vec![lo, hi],
                    color: BLACK,
                },
                Series { x, y, color },
            ],
            log_y: false,
        });
    }
    let cols = models.len().clamp(1, 3);
    let rows = models.len().div_ceil(cols).max(1);
    while panels.len() < rows * cols {
        panels.push(Panel::default());
    }
    write_png(
        path,
        &Figure {
            title: format!(
                "{} ({}): {}; predicted (y) against exact (x)",
                c.name, c.unit, c.definition
            ),
            legend: vec![
                (BLACK, "black: predicted = exact".into()),
                (
                    PALETTE[0],
                    "crosses: one scored sample each (colour by algorithm)".into(),
                ),
            ],
            rows,
            cols,
            panel: (360, 300),
            panels,
        },
    )?;
    Ok(())
}

/// "5 PINO-MBD (direct derivatives), depth 5": the depth tells algorithms 4 and 5 apart.
pub fn alg_label(meta: &ModelMeta) -> String {
    let alg = meta.train.algorithm;
    let rates = meta.layout.rate_outputs();
    let direct = if rates.is_empty() {
        String::new()
    } else {
        format!(", outputs {} directly", rates.join(" "))
    };
    format!(
        "{} {}, depth {}{direct}",
        alg.id(),
        alg.name(),
        meta.model.depth
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use learn_fixtures::synthetic::{write_dataset, SyntheticFiles, SyntheticSpec};
    use pino_learn::config::TrainParams;
    use pino_learn::train::model_meta;

    /// A synthetic dataset's test split, normalised by a model's statistics (no training), with
    /// the index inputs of `system` (checked computable) and the solver's stored columns they
    /// read.
    struct TestSplit {
        layout: Layout,
        meta: ModelMeta,
        items: Prepared,
        idx: Vec<usize>,
        inputs: IndexInputs,
        stored: StoredColumns,
    }

    fn test_split(files: &SyntheticFiles, system: &System, epochs: i64) -> TestSplit {
        let layout = Layout::of(system);
        let (m, t, w) = TrainParams::small(epochs).configs(&layout).unwrap();
        let ds = files.load(&w, false).unwrap();
        let meta = model_meta(&ds, m, t, w).unwrap();
        let (_, items) = files.load_split(&w, Split::Test, &meta.norm).unwrap();
        let idx: Vec<usize> = (0..items.len()).collect();
        let inputs = IndexInputs::of(system, &layout).unwrap();
        assert!(inputs.computable(), "{}", inputs.why_not());
        let ids = idx.iter().map(|&i| items.id(i)).collect();
        let stored =
            StoredColumns::read(std::slice::from_ref(&files.simulation), &inputs, &ids, &w)
                .unwrap();
        TestSplit {
            layout,
            meta,
            items,
            idx,
            inputs,
            stored,
        }
    }

    #[test]
    fn forces_offset_by_5_kn_move_the_peak_force_by_5_kn_and_files_are_written() {
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            n_train: 3,
            n_validation: 1,
            n_test: 2,
            duration: 0.3,
            ..Default::default()
        };
        let files = write_dataset(&spec, dir.path()).unwrap();
        let system = learn_fixtures::synthetic::vehicle_track_system();
        let TestSplit {
            layout,
            meta,
            items,
            idx,
            inputs,
            stored,
        } = test_split(&files, &system, 4);
        // The railway family reads predicted forces and rails, and DOF accelerations.
        assert!(inputs.stored_columns().is_empty());
        let truth = truth_indices(&system, &inputs, &items, &idx, &stored, &meta).unwrap();
        let col = |name: &str| {
            inputs
                .columns()
                .iter()
                .position(|c| c.name == name)
                .unwrap()
        };
        let (peak, reduction, sperling) = (
            col("peak_wheel_rail_force_kn"),
            col("wheel_load_reduction_rate"),
            col("sperling_wz_front"),
        );
        // The truth row's forces are exact: those indices agree to f32 storage.
        for (p, e) in truth.predicted.iter().zip(&truth.exact) {
            assert!(
                (p[peak] - e[peak]).abs() < 1e-3 * e[peak],
                "{} {}",
                p[peak],
                e[peak]
            );
        }
        // A prediction: the truth with every contact force raised by 5 kN.
        let (o, forces) = (layout.n_outputs(), layout.forces());
        let preds: Vec<Physical> = idx
            .iter()
            .map(|&i| {
                let mut ph = to_physical(&items.series(i).unwrap().u, &meta);
                for row in ph.u.chunks_exact_mut(o) {
                    for f in &mut row[forces.clone()] {
                        *f += 5e3;
                    }
                }
                ph
            })
            .collect();
        let m5 = model_indices(&system, &inputs, &items, &idx, &preds, &stored, &meta).unwrap();
        for (k, (p, t)) in m5.predicted.iter().zip(&truth.predicted).enumerate() {
            assert!((p[peak] - t[peak] - 5.0).abs() < 1e-9);
            // W: the sample's static wheel load, the force scale of the dataset.
            let w = items.force_scale(idx[k]);
            let d = t[reduction] - p[reduction];
            assert!((d - 5e3 / w).abs() < 1e-12, "{d}");
            assert_eq!(p[sperling], t[sperling]);
        }
        // The description reads from `indices_from` (0.2 s) on: a wheel unloaded to nothing
        // before it leaves every index as it was; the same dip after it is the deepest.
        assert_eq!(system.indices_from, 0.2);
        let first = eval_config(&system)
            .unwrap()
            .first_at(meta.grid.t0, meta.grid.dt);
        let at = meta.grid.t0 + first as f64 * meta.grid.dt;
        assert!(first > 1 && (at - 0.2).abs() < 1e-9, "{first}: {at} s");
        let dipped = |row: usize| -> Vec<Vec<f64>> {
            let preds: Vec<Physical> = idx
                .iter()
                .map(|&i| {
                    let mut ph = to_physical(&items.series(i).unwrap().u, &meta);
                    ph.u[row * o + forces.start] = 0.0;
                    ph
                })
                .collect();
            model_indices(&system, &inputs, &items, &idx, &preds, &stored, &meta)
                .unwrap()
                .predicted
        };
        assert_eq!(dipped(first - 1), truth.predicted);
        for p in dipped(first) {
            assert_eq!(p[reduction], 1.0, "(W - 0) / W");
        }
        let out = dir.path().join("out");
        std::fs::create_dir_all(&out).unwrap();
        write_indices(&out, Split::Test, &inputs, &layout, &[truth, m5]).unwrap();
        let n = inputs.columns().len();
        let table = pino_data::read_parquet(&out.join("indices_errors.parquet"), None).unwrap();
        assert_eq!(table.num_rows(), 2 * n);
        let mean_abs = table.f64("mean_abs_error").unwrap();
        let peak_row = n + peak; // algorithm 4
        assert!(
            mean_abs[peak_row] > 4.99 && mean_abs[peak_row] < 5.01,
            "{}",
            mean_abs[peak_row]
        );
        for c in inputs.columns() {
            assert!(out
                .join(format!("indices_scatter_{}.png", c.name))
                .is_file());
        }
        assert!(out.join("indices_samples.parquet").is_file());
        // The table for people names each worst sample beside the mean, as the file does.
        let md = std::fs::read_to_string(out.join("indices_errors.md")).unwrap();
        let worst_id = table.i64("worst_abs_sample_id").unwrap()[peak_row];
        let peak_line = md
            .lines()
            .find(|l| l.starts_with("| `peak_wheel_rail_force_kn`"))
            .unwrap();
        assert!(
            md.contains("worst abs (sample) / mean rel % / worst rel %")
                && peak_line.contains(&format!(" 5.0000 / 5.0000 ({worst_id}) / ")),
            "{md}"
        );
    }

    /// The quarter car's indices read a DOF acceleration, an element deflection and a force:
    /// rebuilt from the prediction's own channels (a deflection from the predicted
    /// displacements) they equal the solver's stored values on the exact solution.
    #[test]
    fn a_deflection_and_a_rate_are_rebuilt_from_the_prediction() {
        let dir = tempfile::tempdir().unwrap();
        let source = mbd_system::SystemSource {
            file: "systems/quarter-car.yaml".into(),
            text: include_str!("../../../systems/quarter-car.yaml").into(),
            values: Default::default(),
        };
        let spec = SyntheticSpec {
            n_train: 2,
            n_validation: 1,
            n_test: 2,
            duration: 0.5,
            system: source,
            x0: 0.0,
            ..Default::default()
        };
        let files = write_dataset(&spec, dir.path()).unwrap();
        let info = files.info().unwrap();
        let system = info.system.clone();
        let TestSplit {
            meta,
            items,
            idx,
            inputs,
            stored,
            ..
        } = test_split(&files, &system, 1);
        assert_eq!(inputs.stored_columns(), ["d_suspension"]);
        let truth = truth_indices(&system, &inputs, &items, &idx, &stored, &meta).unwrap();
        let travel = inputs
            .columns()
            .iter()
            .position(|c| c.name == "suspension_travel")
            .unwrap();
        let rms = inputs
            .columns()
            .iter()
            .position(|c| c.name == "sprung_rms_acceleration")
            .unwrap();
        for (p, e) in truth.predicted.iter().zip(&truth.exact) {
            // The deflection is linear in the displacements: exact to their f32 storage.
            assert!(
                (p[travel] - e[travel]).abs() < 1e-5 * e[travel],
                "{} {}",
                p[travel],
                e[travel]
            );
            // The acceleration by central differences: the O(dt^2) floor, well under 1 %.
            assert!(
                e[rms] > 0.0 && (p[rms] - e[rms]).abs() < 1e-2 * e[rms],
                "{} {}",
                p[rms],
                e[rms]
            );
        }
    }

    #[test]
    fn error_statistics_of_known_offsets() {
        let exact = [1.0, 2.0, 4.0];
        let pred = [1.5, 2.0, 3.0];
        let s = index_error(&pred, &exact, &[10, 11, 12]);
        assert!((s.mean_abs - 0.5).abs() < 1e-15);
        assert_eq!((s.worst_abs, s.worst_abs_sample), (1.0, 12));
        assert!((s.mean_rel_pct - 100.0 * (0.5 + 0.0 + 0.25) / 3.0).abs() < 1e-12);
        assert_eq!(s.worst_rel_pct, 50.0);
        let same = index_error(&exact, &exact, &[1, 2, 3]);
        assert!((same.correlation - 1.0).abs() < 1e-15 && same.mean_abs == 0.0);
        let flipped = index_error(&[4.0, 3.0, 1.0], &exact, &[1, 2, 3]);
        assert!(flipped.correlation < -0.9);
        assert!(index_error(&[1.0; 3], &exact, &[1, 2, 3])
            .correlation
            .is_nan());
    }
}
