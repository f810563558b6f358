//! One surrogate per system: several trained models behind one answer. Each index and each
//! predicted channel is answered by the model that was most accurate on it over the validation
//! split ([`build`]), with that model's calibrated interval or band; the user asks one object
//! "what are the indices of this design, and how sure are you?" and never routes by hand.
//!
//! A [`Surrogate`] is loaded from the directory the `surrogate` stage writes (`surrogate.json`
//! and `members/<name>/`, [`manifest`]) or made of a single model ([`Surrogate::of_model`]:
//! every quantity routed to it), so `predict`, the explorer, the studies and Python have one
//! way in. Its answers are assembled from its members' own answers: an index's value, interval
//! and verdict are exactly those of the member that answers it (each member predicts the design
//! once per call), and the combined verdict and the failed limits are judged again on the
//! assembled values. The members share the system, the design space, the time grid, the run
//! controls and the training ranges (checked on load); those are read from the member that
//! answers the most indices, the *primary*.
//!
//! - [`build`]: the `surrogate` stage: each quantity routed to the candidate with the lowest
//!   validation error.
//! - [`manifest`]: `surrogate.json` and the members' files.
//! - [`report`]: the surrogate's errors and coverage on the scored split (for `evaluate`).
#![warn(missing_docs)]

pub mod build;
pub mod manifest;
pub mod report;
#[cfg(test)]
mod tests;

use candle_core::Device;
use manifest::Manifest;
use mbd_engine::{Profile, RunConfig};
use pino_calibration::CalibratedAnswer;
use pino_conformal::Verdict;
use pino_data::{Column, Table};
use pino_indices::IndexConfig;
use pino_outputs::channels::{prediction_channels, ChannelSource};
use pino_outputs::indices_eval::SampleIndices;
pub use pino_outputs::{Error, Result};
use pino_predict::{DesignAnswer, Predictor, ProfileSource, SetPrediction};
use std::path::{Path, PathBuf};

/// A surrogate: its members and which one answers each index and each channel.
pub struct Surrogate {
    members: Vec<Predictor>,
    names: Vec<String>,
    /// Per index column (the description's order): the member answering it.
    index_member: Vec<usize>,
    /// Per predicted channel (the primary's column order, then the others'): its name, the
    /// member answering it and where the member's prediction holds it.
    channels: Vec<(String, usize, ChannelSource)>,
    primary: usize,
    manifest: Option<Manifest>,
    dir: Option<PathBuf>,
}

impl Surrogate {
    /// Loads the surrogate in `dir` (`surrogate.json` and its members, each with its
    /// calibration); refused, naming the file and the model, when a member's files changed or
    /// the members do not share one system and dataset design.
    pub fn load(dir: &Path, device: &Device) -> Result<Self> {
        let manifest = Manifest::load(dir)?;
        let mut members = Vec::with_capacity(manifest.members.len());
        for m in &manifest.members {
            let at = Manifest::member_dir(dir, &m.name);
            let mut p = Predictor::load(&at, device)?;
            p.load_calibration(&at.join(pino_calibration::CALIBRATION_FILE))?;
            of_manifest(&manifest, dir, &m.name, &p)?;
            members.push(p);
        }
        let names: Vec<String> = manifest.members.iter().map(|m| m.name.clone()).collect();
        let member_of = |route: &manifest::Route| -> usize {
            names.iter().position(|n| *n == route.member).unwrap_or(0)
        };
        let index_routes: Vec<(String, usize)> = manifest
            .indices
            .iter()
            .map(|r| (r.name.clone(), member_of(r)))
            .collect();
        let channel_routes: Vec<(String, usize)> = manifest
            .channels
            .iter()
            .map(|r| (r.name.clone(), member_of(r)))
            .collect();
        let file = dir.join(manifest::SURROGATE_FILE);
        let mut s = Self::assemble(members, names, &index_routes, &channel_routes, &file)?;
        s.manifest = Some(manifest);
        s.dir = Some(dir.to_owned());
        Ok(s)
    }

    /// A single model as a surrogate: every quantity is its own.
    pub fn of_model(predictor: Predictor) -> Self {
        let index_member = vec![0; predictor.index_inputs().columns().len()];
        let channels = own_channels(&predictor, 0);
        Self {
            names: vec![predictor.identity().label()],
            members: vec![predictor],
            index_member,
            channels,
            primary: 0,
            manifest: None,
            dir: None,
        }
    }

    /// The surrogate of members `members` named `names` with the routes by quantity name,
    /// checked: every member of one system and design space, every index and channel of the
    /// members routed to one that has it.
    fn assemble(
        members: Vec<Predictor>,
        names: Vec<String>,
        index_routes: &[(String, usize)],
        channel_routes: &[(String, usize)],
        file: &Path,
    ) -> Result<Self> {
        let first = &members[0];
        for (m, name) in members.iter().zip(&names).skip(1) {
            let same = m.meta.system.hash() == first.meta.system.hash()
                && m.meta.training_ranges == first.meta.training_ranges
                && m.meta.grid == first.meta.grid
                && m.meta.data == first.meta.data;
            if !same {
                return Err(Error::format(
                    file,
                    format!(
                        "member `{name}` was trained on another system, dataset or time window than member `{}`: a surrogate's models come from one dataset",
                        names[0]
                    ),
                ));
            }
        }
        let index_names: Vec<&str> = first
            .index_inputs()
            .columns()
            .iter()
            .map(|c| c.name.as_str())
            .collect();
        let mut index_member = vec![0; index_names.len()];
        for (k, name) in index_names.iter().enumerate() {
            match index_routes.iter().find(|(n, _)| n == name) {
                Some(&(_, m)) => index_member[k] = m,
                None => {
                    return Err(Error::format(
                        file,
                        format!("index `{name}` of the system has no route"),
                    ))
                }
            }
        }
        let mut channels = Vec::new();
        for (name, m) in channel_routes {
            let source = prediction_channels(&members[*m].meta.layout)
                .into_iter()
                .find(|(n, _)| n == name)
                .map(|(_, s)| s)
                .ok_or_else(|| {
                    Error::format(
                        file,
                        format!(
                            "channel `{name}` is routed to member `{}`, which does not predict it",
                            names[*m]
                        ),
                    )
                })?;
            channels.push((name.clone(), *m, source));
        }
        let primary = primary_of(&index_member, members.len());
        // The excitations are exact inputs: the primary's.
        channels.extend(
            own_channels(&members[primary], primary)
                .into_iter()
                .filter(|(_, _, s)| matches!(s, ChannelSource::Excitation(_))),
        );
        Ok(Self {
            members,
            names,
            index_member,
            channels,
            primary,
            manifest: None,
            dir: None,
        })
    }

    /// How every member's refusals of designs name them ([`Predictor::name_designs`]).
    pub fn name_designs(&mut self, label: &str) {
        for m in &mut self.members {
            m.name_designs(label);
        }
    }

    /// The member that answers the most indices: the system, design space, time grid, run
    /// controls and training ranges are read from it (the members share them).
    pub fn primary(&self) -> &Predictor {
        &self.members[self.primary]
    }

    /// The members, in the manifest's order.
    pub fn members(&self) -> &[Predictor] {
        &self.members
    }

    /// The members' names.
    pub fn member_names(&self) -> &[String] {
        &self.names
    }

    /// The manifest, when loaded from a surrogate directory.
    pub fn manifest(&self) -> Option<&Manifest> {
        self.manifest.as_ref()
    }

    /// The directory it was loaded from (`None` for a single model).
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// The name of the member answering each index (the description's order).
    pub fn index_routes(&self) -> Vec<&str> {
        self.index_member
            .iter()
            .map(|&m| self.names[m].as_str())
            .collect()
    }

    /// The predicted channels in column order, each with the member answering it and where
    /// its prediction holds it.
    pub fn channels(&self) -> &[(String, usize, ChannelSource)] {
        &self.channels
    }

    /// Loads the calibration of a single model made a surrogate ([`Surrogate::of_model`]);
    /// a surrogate loaded from its directory carries its members' own and refuses another.
    pub fn load_calibration(&mut self, path: &Path) -> Result<&pino_calibration::Calibration> {
        if let Some(dir) = &self.dir {
            return Err(Error::format(
                path,
                format!(
                    "the surrogate {} carries its members' calibrations; another cannot be given",
                    dir.display()
                ),
            ));
        }
        self.members[self.primary].load_calibration(path)
    }

    /// The band of channel `k` ([`Surrogate::channels`]) among its member's calibration
    /// channels; `None` for an excitation or without a calibration with intervals.
    pub fn channel_band(&self, k: usize) -> Option<usize> {
        let (_, m, source) = self.channels.get(k)?;
        let p = &self.members[*m];
        p.calibration().filter(|c| c.has_intervals())?;
        let layout = &p.meta.layout;
        source.band(layout.n_outputs(), layout.n_dofs())
    }

    /// One design's answer from each member's prediction `per` (indexed as
    /// [`Surrogate::members`], `None` for members answering nothing, as
    /// [`Surrogate::forward_with`] gives them): every index from the member answering it, the
    /// failed limits judged on the assembled values; with `coverage` and intervals, each
    /// index's interval and verdict from its member and the bands of the channels in
    /// [`Surrogate::channels`] order (empty for a channel without one).
    pub fn respond(
        &self,
        design: &[f64],
        per: &[Option<&SetPrediction>],
        cfg: &IndexConfig,
        coverage: Option<f64>,
    ) -> Result<(SampleIndices, Option<CalibratedAnswer>)> {
        let computable = self.primary().index_inputs().computable();
        let mut own: Vec<Option<SampleIndices>> = vec![None; self.members.len()];
        let mut calibrated: Vec<Option<CalibratedAnswer>> = vec![None; self.members.len()];
        let banded: Vec<bool> = (0..self.members.len())
            .map(|m| self.channels.iter().any(|(_, x, _)| *x == m))
            .collect();
        for (m, p) in per.iter().enumerate() {
            let Some(p) = p else { continue };
            let member = &self.members[m];
            if computable && (self.index_member.contains(&m) || m == self.primary) {
                own[m] = Some(member.design_indices(design, 0, p, cfg)?);
            }
            if let Some(c) = coverage.filter(|_| self.has_intervals()) {
                let values = own[m].as_ref().map_or(&[][..], |s| &s.values[..]);
                calibrated[m] = member.calibrated(design, p, values, c, banded[m])?;
            }
        }
        let indices = if computable {
            self.assemble_values(own.iter().map(Option::as_ref).collect(), cfg)?
        } else {
            SampleIndices {
                values: Vec::new(),
                window_s: f64::NAN,
                failed: Vec::new(),
            }
        };
        let refs: Vec<Option<&CalibratedAnswer>> = calibrated.iter().map(Option::as_ref).collect();
        let answer = if computable {
            self.assemble_calibrated(&refs)
        } else {
            refs[self.primary].cloned().map(|mut a| {
                a.bands = Vec::new();
                a
            })
        };
        let answer = answer.map(|mut a| {
            a.bands = (0..self.channels.len())
                .map(|k| {
                    let m = self.channels[k].1;
                    self.channel_band(k)
                        .and_then(|b| refs[m]?.bands.get(b).cloned())
                        .unwrap_or_default()
                })
                .collect();
            a
        });
        Ok((indices, answer))
    }

    /// Whether every member answering a quantity has a calibration with intervals.
    pub fn has_intervals(&self) -> bool {
        self.used().all(|m| {
            self.members[m]
                .calibration()
                .is_some_and(|c| c.has_intervals())
        })
    }

    /// The members answering some index or channel.
    fn used(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.members.len()).filter(|m| {
            self.index_member.contains(m) || self.channels.iter().any(|(_, x, _)| x == m)
        })
    }

    /// The level of the answers' intervals ([`Predictor::interval_level`]): `None` unless
    /// every member answering a quantity has intervals; refused when one cannot support it.
    pub fn interval_level(&self, coverage: Option<f64>) -> Result<Option<f64>> {
        let mut level = None;
        for m in self.used() {
            match self.members[m].interval_level(coverage)? {
                Some(l) => level = Some(l),
                None => return Ok(None),
            }
        }
        Ok(level)
    }

    /// Each design predicted by every member answering some quantity (`None` for the others),
    /// in one forward pass per member.
    pub fn forward_with(
        &self,
        first: usize,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
    ) -> Result<Vec<Option<Vec<SetPrediction>>>> {
        let used: Vec<usize> = self.used().collect();
        (0..self.members.len())
            .map(|m| {
                if used.contains(&m) {
                    self.members[m]
                        .forward_with(first, sets, profiles, run)
                        .map(Some)
                } else {
                    Ok(None)
                }
            })
            .collect()
    }

    /// Every design's indices (batches of `batch` sets), each from the member answering it.
    pub fn indices(
        &self,
        sets: &[Vec<f64>],
        profiles: &[Option<Profile>],
        run: &RunConfig,
        cfg: &IndexConfig,
        batch: usize,
    ) -> Result<Vec<SampleIndices>> {
        let per = self.per_index_member(|p| p.indices(sets, profiles, run, cfg, batch))?;
        (0..sets.len())
            .map(|k| self.assemble_indices(&per, k, cfg))
            .collect()
    }

    /// Every design's indices with their intervals and verdicts at `coverage` (with a
    /// calibration), each from the member answering it ([`Predictor::answers`]).
    pub fn answers(
        &self,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
        cfg: &IndexConfig,
        batch: usize,
        coverage: f64,
    ) -> Result<Vec<DesignAnswer>> {
        let per =
            self.per_index_member(|p| p.answers(sets, profiles, run, cfg, batch, coverage))?;
        (0..sets.len())
            .map(|k| {
                let indices = per.iter().map(|a| a.as_ref().map(|a| &a[k].indices));
                let indices = self.assemble_values(indices.collect(), cfg)?;
                let calibrated: Vec<Option<&CalibratedAnswer>> = per
                    .iter()
                    .map(|a| a.as_ref().and_then(|a| a[k].calibrated.as_ref()))
                    .collect();
                Ok(DesignAnswer {
                    indices,
                    calibrated: self.assemble_calibrated(&calibrated),
                })
            })
            .collect()
    }

    /// `f` of every member answering some index (`None` for the others).
    fn per_index_member<T>(
        &self,
        f: impl Fn(&Predictor) -> Result<Vec<T>>,
    ) -> Result<Vec<Option<Vec<T>>>> {
        (0..self.members.len())
            .map(|m| {
                if self.index_member.contains(&m) {
                    f(&self.members[m]).map(Some)
                } else {
                    Ok(None)
                }
            })
            .collect()
    }

    fn assemble_indices(
        &self,
        per: &[Option<Vec<SampleIndices>>],
        k: usize,
        cfg: &IndexConfig,
    ) -> Result<SampleIndices> {
        self.assemble_values(per.iter().map(|a| a.as_ref().map(|a| &a[k])).collect(), cfg)
    }

    /// Each index's value from the member answering it (`per`: one per member, `None` for
    /// those answering none); the failed limits judged on the assembled values.
    fn assemble_values(
        &self,
        per: Vec<Option<&SampleIndices>>,
        cfg: &IndexConfig,
    ) -> Result<SampleIndices> {
        let values: Vec<f64> = self
            .index_member
            .iter()
            .enumerate()
            .map(|(k, &m)| per[m].map_or(f64::NAN, |s| s.values[k]))
            .collect();
        let primary = self.primary();
        let failed = primary
            .index_inputs()
            .failed_of(primary.system(), &values, cfg);
        let window_s = per[self.primary].map_or(f64::NAN, |s| s.window_s);
        Ok(SampleIndices {
            values,
            window_s,
            failed,
        })
    }

    /// Each index's interval and verdict from the member answering it, the combined verdict
    /// judged again; the relative residual and `extrapolated` are the primary's. `None` unless
    /// every member answering an index has a calibrated answer.
    fn assemble_calibrated(&self, per: &[Option<&CalibratedAnswer>]) -> Option<CalibratedAnswer> {
        let base = per[self.primary]?;
        let mut indices = Vec::with_capacity(self.index_member.len());
        let mut verdicts = Vec::with_capacity(self.index_member.len());
        for (k, &m) in self.index_member.iter().enumerate() {
            let a = per[m]?;
            indices.push(*a.indices.get(k)?);
            verdicts.push(*a.verdicts.get(k)?);
        }
        Some(CalibratedAnswer {
            coverage: base.coverage,
            extrapolated: base.extrapolated,
            relative_residual: base.relative_residual,
            verdict: Verdict::combine(verdicts.iter().flatten().copied()),
            indices,
            verdicts,
            bands: Vec::new(),
        })
    }

    /// The time histories of every design as one table ([`Predictor::histories`]): each
    /// channel (and its band `_lo`/`_hi`, with a calibration and `coverage`) from the member
    /// answering it, the excitations from the primary.
    pub fn histories(
        &self,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
        batch: usize,
        coverage: Option<f64>,
    ) -> Result<Table> {
        let tables: Vec<Option<Table>> = (0..self.members.len())
            .map(|m| {
                let answers = m == self.primary || self.channels.iter().any(|(_, x, _)| *x == m);
                answers
                    .then(|| self.members[m].histories(sets, profiles, run, batch, coverage))
                    .transpose()
            })
            .collect::<Result<_>>()?;
        let base = tables[self.primary].as_ref().ok_or_else(|| {
            Error::format(
                Path::new("surrogate"),
                "the primary member predicted nothing".into(),
            )
        })?;
        let mut out = Table::default().with_units(base.units().clone());
        for key in ["set", pino_data::schema::TIME] {
            out.push(key, base.column(key)?.clone())?;
        }
        let columns = |suffix: &str| -> Result<Vec<(String, Column, Option<String>)>> {
            let mut v = Vec::new();
            for (name, m, _) in &self.channels {
                let t = tables[*m].as_ref().unwrap_or(base);
                let col = format!("{name}{suffix}");
                if let Ok(c) = t.column(&col) {
                    v.push((col.clone(), c.clone(), t.unit(&col).map(str::to_owned)));
                }
            }
            Ok(v)
        };
        let banded = self.channels.iter().all(|(name, m, s)| {
            matches!(s, ChannelSource::Excitation(_))
                || tables[*m]
                    .as_ref()
                    .is_some_and(|t| t.column(&format!("{name}_lo")).is_ok())
        }) && coverage.is_some();
        let mut all = columns("")?;
        if banded {
            for (lo, hi) in columns("_lo")?.into_iter().zip(columns("_hi")?) {
                all.push(lo);
                all.push(hi);
            }
        }
        for (name, col, unit) in all {
            if let Some(u) = unit {
                out.add_units([(name.clone(), u)])?;
            }
            out.push(&name, col)?;
        }
        Ok(out)
    }

    /// [`Surrogate::histories`] with the column [`pino_predict::OUTSIDE_COLUMN`] last (the
    /// table of `predict --out` and of the Python package's `predict`).
    pub fn histories_flagged(
        &self,
        sets: &[Vec<f64>],
        profiles: &ProfileSource<'_>,
        run: &RunConfig,
        batch: usize,
        coverage: Option<f64>,
    ) -> Result<Table> {
        let mut table = self.histories(sets, profiles, run, batch, coverage)?;
        self.primary().flag_rows(&mut table, sets)?;
        Ok(table)
    }

    /// The indices table of `predict` ([`Predictor::indices_table`]) of assembled answers.
    pub fn indices_table(
        &self,
        sets: &[Vec<f64>],
        answers: &[DesignAnswer],
        outside: &[Vec<pino_learn::checkpoint::OutOfRange>],
    ) -> Result<Table> {
        self.primary().indices_table(sets, answers, outside)
    }
}

/// Of `n` members, the one answering the most indices (`index_member`: per index, its member;
/// ties: the first).
pub(crate) fn primary_of(index_member: &[usize], n: usize) -> usize {
    (0..n)
        .max_by_key(|&m| {
            (
                index_member.iter().filter(|&&x| x == m).count(),
                std::cmp::Reverse(m),
            )
        })
        .unwrap_or(0)
}

/// A member `name` loaded as `p` is of the manifest's system and dataset design: a manifest
/// of another system (or edited) beside these members is refused, naming both.
fn of_manifest(manifest: &Manifest, dir: &Path, name: &str, p: &Predictor) -> Result<()> {
    let rebuild = "rebuild the surrogate (`pipeline run surrogate`)";
    let system = &p.identity().system;
    let why = if *system != manifest.system {
        format!(
            "the manifest is of system `{}`, but member model `{name}` is of system `{system}`: {rebuild}",
            manifest.system
        )
    } else if p.calibration().is_some_and(|c| c.design != manifest.design) {
        format!(
            "member model `{name}` was calibrated on another dataset design (description or sampling ranges) than the manifest records: {rebuild}"
        )
    } else {
        return Ok(());
    };
    Err(Error::format(&dir.join(manifest::SURROGATE_FILE), why))
}

/// A member's own channels, all answered by it (`m`).
fn own_channels(p: &Predictor, m: usize) -> Vec<(String, usize, ChannelSource)> {
    prediction_channels(&p.meta.layout)
        .into_iter()
        .map(|(name, source)| (name, m, source))
        .collect()
}
