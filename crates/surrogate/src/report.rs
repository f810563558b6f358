//! The surrogate against the solver on the scored split (`evaluate`'s `surrogate_*` files):
//! per index and per channel, the member that answers it, its error, and its calibrated
//! interval's coverage and width at the default level, with the worst conditional cell
//! (difficulty terciles, parameter quartiles). Each row is the answering member's own numbers:
//! a surrogate's answer to a quantity is that member's.
//!
//! Files: `surrogate_errors.{parquet,csv}` (one row per quantity) and `surrogate.md`.

use super::manifest::Manifest;
use crate::Result;
use atomic_file::write_atomic;
use candle_core::Device;
use pino_calibration::coverage::{ConditionalRow, CoverageAccumulator, CoverageRow};
use pino_calibration::scored::{band_channels, Run, Scorer};
use pino_calibration::{Calibration, ModelIdentity, CALIBRATION_FILE, DEFAULT_COVERAGE};
use pino_data::{write_parquet, Column, Table};
use pino_learn::checkpoint::load_model;
use pino_learn::data::Split;
use pino_learn::layout::Layout;
use pino_learn::spectral::Transform;
use pino_outputs::channels::prediction_channels;
use pino_outputs::indices_eval::{index_error, IndexInputs};
use pino_outputs::split::{EvalData, ScoredData};
use report::csv::write_csv;
use std::path::Path;

/// One quantity of the surrogate on the scored split.
#[derive(Debug, Clone, PartialEq)]
pub struct SurrogateRow {
    /// `index` or `channel`.
    pub kind: &'static str,
    /// Its name.
    pub quantity: String,
    /// Its unit.
    pub unit: String,
    /// The member answering it.
    pub member: String,
    /// Scored samples.
    pub n: usize,
    /// Mean relative error (%): an index's `|y - f| / |y|`, a channel's relative L2 error.
    pub mean_rel_pct: f64,
    /// The largest relative error (%) and its sample.
    pub worst_rel_pct: f64,
    /// Sample id of the largest error.
    pub worst_sample: i64,
    /// Coverage of the interval (band) at [`DEFAULT_COVERAGE`] (NaN without a calibration).
    pub coverage: f64,
    /// Its mean width over the quantity's standard deviation on the split.
    pub width_over_std: f64,
    /// Its mean width, in the unit.
    pub mean_width: f64,
    /// The lowest conditional coverage and its cell (`group: bin`).
    pub worst_cell: Option<(f64, String)>,
}

/// The rows of the surrogate in `dir` on `split` of `data`, in the manifest's order.
pub fn surrogate_rows(
    data: &EvalData<'_>,
    dir: &Path,
    split: Split,
    batch: usize,
    device: &Device,
) -> Result<Vec<SurrogateRow>> {
    let manifest = Manifest::load(dir)?;
    let system = &data.info.system;
    let index_inputs = IndexInputs::of(system, &Layout::of(system))?;
    let mut rows = Vec::new();
    for member in &manifest.members {
        let at = Manifest::member_dir(dir, &member.name);
        let (model, meta) = load_model(&at, Transform::for_device(device), device)?;
        let calibration = Calibration::load(&at.join(CALIBRATION_FILE), &ModelIdentity::of(&at)?)?;
        let scored = ScoredData::load(data, split, &meta, &index_inputs)?;
        let run = Run {
            model: &model,
            meta: &meta,
            batch,
            device,
        };
        let scores = MemberScores::of(data, run, &calibration, &scored)?;
        let cov = Coverage {
            rows: &scores.coverage,
            conditional: &scores.conditional,
        };
        scores.index_rows(&manifest, &member.name, &cov, &mut rows);
        scores.channel_rows(&manifest, &member.name, &meta.layout, &cov, &mut rows);
    }
    // The manifest's order: indices, then channels.
    let order = |r: &SurrogateRow| {
        let list = if r.kind == "index" {
            &manifest.indices
        } else {
            &manifest.channels
        };
        (
            r.kind != "index",
            list.iter().position(|x| x.name == r.quantity),
        )
    };
    rows.sort_by_key(order);
    Ok(rows)
}

/// One member's answers on the scored split: per sample its indices and each channel's
/// relative error, and its calibration's coverage.
struct MemberScores {
    ids: Vec<i64>,
    pred: Vec<Vec<f64>>,
    exact: Vec<Vec<f64>>,
    /// Per sample and channel: the relative L2 error and the sample id.
    curves: Vec<Vec<(f64, i64)>>,
    coverage: Vec<CoverageRow>,
    conditional: Vec<ConditionalRow>,
}

impl MemberScores {
    /// Scores the member of `run` on `scored` (its coverage where `calibration` has intervals).
    fn of(
        data: &EvalData<'_>,
        run: Run<'_>,
        calibration: &Calibration,
        scored: &ScoredData,
    ) -> Result<Self> {
        let system = &data.info.system;
        let model_inputs = IndexInputs::of(system, &run.meta.layout)?;
        let scorer = Scorer::new(system, run, &model_inputs)?;
        let mut acc = CoverageAccumulator::new(calibration);
        let (mut ids, mut pred, mut exact) = (Vec::new(), Vec::new(), Vec::new());
        let mut curves: Vec<Vec<(f64, i64)>> = Vec::new();
        let idx: Vec<usize> = (0..scored.items.len()).collect();
        scorer.for_each(&scored.items, &idx, &scored.stored, &mut |s| {
            if calibration.has_intervals() {
                acc.add(s)?;
            }
            ids.push(s.id);
            pred.push(s.predicted_indices.clone());
            exact.push(s.exact_indices.clone());
            curves.push(
                s.predicted
                    .iter()
                    .zip(&s.exact)
                    .map(|(p, x)| (relative_l2(p, x), s.id))
                    .collect(),
            );
            Ok(())
        })?;
        let (coverage, conditional) = acc.finish()?;
        Ok(Self {
            ids,
            pred,
            exact,
            curves,
            coverage,
            conditional,
        })
    }

    /// The rows of the indices routed to `member`.
    fn index_rows(
        &self,
        manifest: &Manifest,
        member: &str,
        cov: &Coverage<'_>,
        rows: &mut Vec<SurrogateRow>,
    ) {
        let ids = &self.ids;
        for (k, route) in manifest.indices.iter().enumerate() {
            if route.member != member {
                continue;
            }
            let column = |rows: &[Vec<f64>]| -> Vec<f64> { rows.iter().map(|r| r[k]).collect() };
            let (pred, exact) = (column(&self.pred), column(&self.exact));
            let e = index_error(&pred, &exact, ids);
            rows.push(cov.row(
                "index",
                route,
                &route.name,
                ids.len(),
                [e.mean_rel_pct, e.worst_rel_pct],
                if e.worst_rel_pct > 0.0 {
                    worst_of(&pred, &exact, ids)
                } else {
                    -1
                },
            ));
        }
    }

    /// The rows of the channels routed to `member` (of `layout`).
    fn channel_rows(
        &self,
        manifest: &Manifest,
        member: &str,
        layout: &Layout,
        cov: &Coverage<'_>,
        rows: &mut Vec<SurrogateRow>,
    ) {
        let bands = band_channels(layout);
        let (o, d) = (layout.n_outputs(), layout.n_dofs());
        for route in manifest.channels.iter().filter(|r| r.member == member) {
            let Some(band) = prediction_channels(layout)
                .into_iter()
                .find(|(n, _)| *n == route.name)
                .and_then(|(_, s)| s.band(o, d))
            else {
                continue;
            };
            let errs: Vec<(f64, i64)> = self.curves.iter().map(|c| c[band]).collect();
            let finite: Vec<&(f64, i64)> = errs.iter().filter(|e| e.0.is_finite()).collect();
            let mean = 100.0 * finite.iter().map(|e| e.0).sum::<f64>() / finite.len().max(1) as f64;
            let worst = finite
                .iter()
                .copied()
                .fold((0.0, -1), |b, &(v, id)| if v > b.0 { (v, id) } else { b });
            rows.push(cov.row(
                "channel",
                route,
                &bands[band].name,
                errs.len(),
                [mean, 100.0 * worst.0],
                worst.1,
            ));
        }
    }
}

/// A member's coverage rows and conditional cells.
struct Coverage<'a> {
    rows: &'a [CoverageRow],
    conditional: &'a [ConditionalRow],
}

impl Coverage<'_> {
    /// The row of `route` (whose calibrated quantity is `band`) with its errors.
    fn row(
        &self,
        kind: &'static str,
        route: &super::manifest::Route,
        band: &str,
        n: usize,
        [mean_rel_pct, worst_rel_pct]: [f64; 2],
        worst_sample: i64,
    ) -> SurrogateRow {
        let at = self.rows.iter().find(|r| {
            r.kind == kind && r.quantity == band && r.chosen && r.level == DEFAULT_COVERAGE
        });
        let worst_cell = self
            .conditional
            .iter()
            .filter(|c| c.kind == kind && c.quantity == band)
            .min_by(|a, b| a.coverage.total_cmp(&b.coverage))
            .map(|c| (c.coverage, format!("{}: {}", c.group, c.bin)));
        SurrogateRow {
            kind,
            quantity: route.name.clone(),
            unit: route.unit.clone(),
            member: route.member.clone(),
            n,
            mean_rel_pct,
            worst_rel_pct,
            worst_sample,
            coverage: at.map_or(f64::NAN, |r| r.coverage),
            width_over_std: at.map_or(f64::NAN, |r| r.width_over_std),
            mean_width: at.map_or(f64::NAN, |r| r.mean_width),
            worst_cell,
        }
    }
}

/// `||x - p|| / ||x||` (NaN when `x` is zero).
fn relative_l2(p: &[f64], x: &[f64]) -> f64 {
    let (mut e, mut n) = (0.0, 0.0);
    for (p, x) in p.iter().zip(x) {
        e += (x - p) * (x - p);
        n += x * x;
    }
    if n > 0.0 {
        (e / n).sqrt()
    } else {
        f64::NAN
    }
}

/// The sample id of the largest relative error.
fn worst_of(pred: &[f64], exact: &[f64], ids: &[i64]) -> i64 {
    let rel = |k: usize| {
        if exact[k] == 0.0 {
            0.0
        } else {
            ((pred[k] - exact[k]) / exact[k]).abs()
        }
    };
    (0..ids.len())
        .max_by(|&a, &b| rel(a).total_cmp(&rel(b)))
        .map_or(-1, |k| ids[k])
}

/// Writes `surrogate_errors.{parquet,csv}` and `surrogate.md` into `out`.
pub fn write_surrogate(out: &Path, split: Split, rows: &[SurrogateRow]) -> Result<()> {
    let mut t = Table::default();
    let dimensionless = pino_data::units::DIMENSIONLESS;
    t.add_units([
        ("member", dimensionless),
        ("worst_rel_sample_id", dimensionless),
        ("worst_cell_coverage", dimensionless),
        ("worst_cell", dimensionless),
    ])?;
    let s = |f: &dyn Fn(&SurrogateRow) -> String| Column::Str(rows.iter().map(f).collect());
    let x = |f: &dyn Fn(&SurrogateRow) -> f64| Column::F64(rows.iter().map(f).collect());
    t.push("kind", s(&|r| r.kind.to_owned()))?;
    t.push("quantity", s(&|r| r.quantity.clone()))?;
    t.push("unit", s(&|r| r.unit.clone()))?;
    t.push("member", s(&|r| r.member.clone()))?;
    t.push("n", Column::I64(rows.iter().map(|r| r.n as i64).collect()))?;
    t.push("mean_rel_error_pct", x(&|r| r.mean_rel_pct))?;
    t.push("worst_rel_error_pct", x(&|r| r.worst_rel_pct))?;
    t.push(
        "worst_rel_sample_id",
        Column::I64(rows.iter().map(|r| r.worst_sample).collect()),
    )?;
    t.push("level", x(&|_| DEFAULT_COVERAGE))?;
    t.push("coverage", x(&|r| r.coverage))?;
    t.push("mean_width", x(&|r| r.mean_width))?;
    t.push("width_over_std", x(&|r| r.width_over_std))?;
    t.push(
        "worst_cell_coverage",
        x(&|r| r.worst_cell.as_ref().map_or(f64::NAN, |c| c.0)),
    )?;
    t.push(
        "worst_cell",
        Column::OptStr(
            rows.iter()
                .map(|r| r.worst_cell.as_ref().map(|c| c.1.clone()))
                .collect(),
        ),
    )?;
    write_parquet(&out.join("surrogate_errors.parquet"), &t)?;
    write_csv(&out.join("surrogate_errors.csv"), &t)?;
    let mut md = format!(
        "# The surrogate against the solver ({} split)\n\nEach quantity is answered by the member chosen for it on the validation split (`surrogate.json`); its error is that member's against the solver, its interval that member's calibration at {DEFAULT_COVERAGE}: coverage, mean width over the quantity's standard deviation on this split, and the lowest coverage of a difficulty tercile or parameter quartile.\n\n| kind | quantity | member | mean rel. error % | worst % (sample) | coverage | width / std | worst cell |\n|---|---|---|---|---|---|---|---|\n",
        split.as_str()
    );
    for r in rows {
        md.push_str(&format!(
            "| {} | `{}` | `{}` | {:.2} | {:.1} ({}) | {} | {} | {} |\n",
            r.kind,
            r.quantity,
            r.member,
            r.mean_rel_pct,
            r.worst_rel_pct,
            r.worst_sample,
            fmt(r.coverage, 3),
            fmt(r.width_over_std, 2),
            r.worst_cell
                .as_ref()
                .map_or("-".into(), |(c, w)| format!("{c:.2} ({w})"))
        ));
    }
    Ok(write_atomic(&out.join("surrogate.md"), md.as_bytes())?)
}

fn fmt(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "-".into()
    }
}
