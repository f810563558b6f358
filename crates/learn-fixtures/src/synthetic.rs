//! Small, exactly consistent datasets for tests and benchmarks, simulated by the generic engine
//! from a system description: the artifacts the physics stages would write, in one directory.
//!
//! The default is the vehicle-track description on a short track (`n_f` = 120 supports of
//! 0.6 m, 72 m of rail, 60 modes) with the vehicle starting at `x0` = 5 m, every other value
//! the description's; [`SyntheticSpec::system`] takes any description text and its overrides.
//! Parameters are drawn as `sample-params` draws them, profiles as `irregularity` makes them
//! (spacing 0.1 m over the beam's length, or the longest wavelength if longer), the records as `simulate` runs them (equilibrium
//! start, `dt` 1e-4 s, 1 kHz output): the stored `(z, v, a)` satisfy the equations of motion to
//! round-off.
//!
//! Files written: `params.parquet`, `ranges.parquet`, `system.json`, `run.json`,
//! `simulation.parquet`, `weights.parquet` (phi of the training samples, [`pino_learn::weights`]).

use mbd_dataset::{ProfileParams, SamplingPlan, SplitSizes};
use mbd_engine::{Profile, RunConfig, SampleInput, StartMode};
use mbd_system::{Override, SystemSource};
use pino_data::units::Units;
use pino_data::{schema, write_parquet, Column, StreamWriter, Table};
use pino_learn::config::WindowConfig;
use pino_learn::data::{load_dataset, load_split, Dataset, DatasetInfo, Prepared, Split};
use pino_learn::layout::Layout;
use pino_learn::weights::{magnitude_weights, WeightConfig};
use pino_learn::{Error, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The vehicle-track description (the repository's `systems/vtcd.yaml`).
pub const VEHICLE_TRACK: &str = include_str!("../../../systems/vtcd.yaml");

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticSpec {
    /// Training samples (ids `0..n_train`).
    pub n_train: u64,
    /// Validation samples (the following ids).
    pub n_validation: u64,
    /// Test samples (the ids after validation).
    pub n_test: u64,
    /// Calibration samples (the ids after the test ones; needs a test split).
    pub n_calibration: u64,
    /// Record duration (s).
    pub duration: f64,
    /// Seed of parameters, profiles and weights.
    pub seed: u64,
    /// Noise ratio of the ODE magnitude weights.
    pub noise_ratio: f64,
    /// The description and its overrides.
    pub system: SystemSource,
    /// Where the moving frame starts (m).
    pub x0: f64,
}

impl SyntheticSpec {
    /// The short-track vehicle-track model.
    pub fn vehicle_track() -> SystemSource {
        SystemSource {
            file: "systems/vtcd.yaml".into(),
            text: VEHICLE_TRACK.into(),
            values: BTreeMap::from([
                ("n_f".to_owned(), Override::Value(120.0)),
                ("n_m".to_owned(), Override::Value(60.0)),
            ]),
        }
    }
}

impl SyntheticSpec {
    /// The vehicle-track model with a rail long enough for records of `duration` s from
    /// `x0` = 5 m at the highest sampled speed (supports in steps of 60, half as many modes).
    pub fn vehicle_track_for(duration: f64) -> SystemSource {
        let mut source = Self::vehicle_track();
        let system = source
            .compile()
            .expect("the repository's description compiles");
        let values = system
            .values(&system.nominal())
            .expect("the nominal design is the system's");
        let at = |name: &str| values[system.parameter(name).expect("a vehicle-track parameter")];
        let hi = |name: &str| {
            let k = system
                .sampled_names()
                .iter()
                .position(|n| *n == name)
                .expect("sampled");
            system.ranges()[k][1]
        };
        let need = 5.0 + hi("v_kmh") / 3.6 * duration + 2.0 * (hi("l_c") + hi("l_t")) + 10.0;
        let n_f = ((need / at("s") / 60.0).ceil() * 60.0).max(120.0);
        source.values.insert("n_f".to_owned(), Override::Value(n_f));
        source
            .values
            .insert("n_m".to_owned(), Override::Value(n_f / 2.0));
        source
    }
}

impl Default for SyntheticSpec {
    fn default() -> Self {
        Self {
            n_train: 8,
            n_validation: 2,
            n_test: 1,
            n_calibration: 0,
            duration: 0.3,
            seed: 1,
            noise_ratio: 0.02,
            system: Self::vehicle_track(),
            x0: 5.0,
        }
    }
}

/// The short-track vehicle-track system of [`SyntheticSpec::vehicle_track`], compiled.
pub fn vehicle_track_system() -> Arc<mbd_system::System> {
    Arc::new(
        SyntheticSpec::vehicle_track()
            .compile()
            .expect("the repository's description compiles"),
    )
}

/// Its layout.
pub fn vehicle_track_layout() -> Layout {
    Layout::of(&vehicle_track_system())
}

/// Where [`write_dataset`] put the files.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticFiles {
    /// The directory (one shard of every artifact).
    pub dir: PathBuf,
    /// `params.parquet`.
    pub params: PathBuf,
    /// `simulation.parquet`.
    pub simulation: PathBuf,
    /// `weights.parquet`.
    pub weights: PathBuf,
    /// `system.json`.
    pub system: PathBuf,
}

impl SyntheticFiles {
    /// The dataset's description and run controls, as the learning stages read them.
    pub fn info(&self) -> Result<DatasetInfo> {
        DatasetInfo::from_dirs(std::slice::from_ref(&self.dir))
    }

    /// The training and validation samples (with the magnitude weights when `weights`).
    pub fn load(&self, window: &WindowConfig, weights: bool) -> Result<Dataset> {
        let w = weights.then_some(self.weights.as_path());
        load_dataset(
            &self.info()?,
            &self.params,
            std::slice::from_ref(&self.simulation),
            w,
            window,
        )
    }

    /// The samples of `split` alone, z-scored with `norm` (as `evaluate` reads them).
    pub fn load_split(
        &self,
        window: &WindowConfig,
        split: Split,
        norm: &pino_learn::norm::Normalisation,
    ) -> Result<(Dataset, Prepared)> {
        load_split(
            &self.info()?,
            &self.params,
            std::slice::from_ref(&self.simulation),
            window,
            split,
            norm,
        )
    }
}

/// The profiles' controls: spacing 0.1 m over the longest beam (or 1 km of road), and at
/// least the longest wavelength of any generated profile (the generator's band must fit).
fn profile_controls(system: &mbd_system::System, seed: u64) -> ProfileParams {
    let length = system
        .beams
        .iter()
        .map(|b| {
            let nominal = system.values(&system.nominal());
            b.length
                .eval(&nominal.expect("the nominal design is the system's"))
        })
        .fold(0.0, f64::max);
    let longest = system
        .profiles
        .iter()
        .filter_map(|p| match p {
            mbd_system::system::Profile::Generated { wavelengths, .. } => Some(wavelengths[1]),
            _ => None,
        })
        .fold(0.0, f64::max);
    ProfileParams {
        seed,
        dx: 0.1,
        length: if length > 0.0 {
            length.max(longest)
        } else {
            1000.0_f64.max(longest)
        },
    }
}

/// `weights.parquet`: the magnitude weights phi of the training samples, by id.
fn write_weights(
    path: &Path,
    units: &Units,
    layout: &Layout,
    phi: &[(i64, Vec<f64>)],
) -> Result<()> {
    let mut wt = Table::default().with_units(units.clone());
    wt.push(
        schema::SAMPLE_ID,
        Column::I64(phi.iter().map(|p| p.0).collect()),
    )?;
    for (i, name) in layout.phi_columns().iter().enumerate() {
        wt.push(name, Column::F64(phi.iter().map(|p| p.1[i]).collect()))?;
    }
    write_parquet(path, &wt)?;
    Ok(())
}

/// Simulates the dataset of `spec` into `dir` (with `run.json`, as `simulate` writes it).
pub fn write_dataset(spec: &SyntheticSpec, dir: &Path) -> Result<SyntheticFiles> {
    let bad = |message: String| dataset_error(dir, message);
    let system = Arc::new(spec.system.compile().map_err(|e| bad(e.to_string()))?);
    let units = pino_data::system::units_of(&system)?;
    let (plan, draws) = draw_samples(spec, &system, dir)?;
    let splits: Vec<&str> = (0..draws.len() as u64)
        .map(|id| plan.split(id).as_str())
        .collect();
    let params_path =
        pino_data::system::write_sample_params(dir, &system, &splits, &draws, plan.ranges())?;
    pino_data::system::write_record(dir, &spec.system)?;

    // Profiles, then the runs.
    let controls = profile_controls(&system, spec.seed);
    let generators =
        mbd_dataset::profile_generators(&system, &controls).map_err(|e| bad(e.to_string()))?;
    let designs: Vec<mbd_system::Sampled> = draws
        .iter()
        .map(|d| system.sampled_values(d.as_slice()))
        .collect::<std::result::Result<_, _>>()?;
    let config = RunConfig {
        duration: spec.duration,
        dt: 1e-4,
        output_every: 10,
        start: StartMode::Equilibrium,
        startup_zero_fraction: 0.0,
        startup_ramp_fraction: 0.0,
        x0: spec.x0,
    };
    let engines = mbd_engine::prepare(&system, &config, sample_inputs(&generators, &designs))
        .map_err(|(id, e)| bad(format!("sample {id}: {e}")))?;
    let sim_path = dir.join(pino_data::artifacts::SIMULATION_FILE);
    let layout = Layout::of(&system);
    let simulation = Simulation {
        system: &system,
        units: &units,
        plan: &plan,
        designs: &designs,
        layout: &layout,
        weights: WeightConfig {
            seed: spec.seed,
            noise_ratio: spec.noise_ratio,
            window_start_fraction: 0.0,
        },
        record_dt: config.dt * config.output_every as f64,
    };
    let phi = simulation.run(&engines, &sim_path, dir)?;
    let weights_path = dir.join(pino_data::artifacts::WEIGHTS_FILE);
    write_weights(&weights_path, &units, &layout, &phi)?;
    let settings = pino_learn::checkpoint::DataSettings {
        run: config,
        profiles: generators.iter().any(Option::is_some).then_some(controls),
    };
    pino_data::system::write_json(
        &dir.join(pino_data::artifacts::RUN_FILE),
        &serde_json::to_value(&settings).map_err(|e| bad(e.to_string()))?,
    )?;
    Ok(SyntheticFiles {
        dir: dir.to_owned(),
        params: params_path,
        simulation: sim_path,
        weights: weights_path,
        system: dir.join(mbd_system::SYSTEM_FILE),
    })
}

/// The error of the synthetic dataset in `dir`.
fn dataset_error(dir: &Path, message: String) -> Error {
    Error::Dataset {
        path: dir.to_owned(),
        message,
    }
}

/// The sampling plan of `spec` and the sampled parameters of its samples, by id.
fn draw_samples(
    spec: &SyntheticSpec,
    system: &mbd_system::System,
    dir: &Path,
) -> Result<(SamplingPlan, Vec<Vec<f64>>)> {
    let bad = |message: String| dataset_error(dir, message);
    // A sampling plan has all three splits (as every pipeline's data); a synthetic dataset may
    // leave out the test split (the validation fallback of `evaluate`): the plan then holds one
    // test id that is not written. Ids before it are drawn and split alike either way.
    if spec.n_test == 0 && spec.n_calibration > 0 {
        return Err(bad(
            "a synthetic calibration split needs a test split (its ids follow the test ids)".into(),
        ));
    }
    let sizes = SplitSizes {
        seed: spec.seed,
        n_train: spec.n_train,
        n_validation: spec.n_validation,
        n_test: spec.n_test.max(1),
        n_calibration: spec.n_calibration,
    };
    let plan = SamplingPlan::new(sizes, system).map_err(|e| bad(e.to_string()))?;
    let n = spec.n_train + spec.n_validation + spec.n_test + spec.n_calibration;
    let draws = (0..n).map(|id| plan.draw(id)).collect();
    Ok((plan, draws))
}

/// The engines' inputs: sample `id` has design `designs[id]` and each generated profile's
/// realisation `id`.
fn sample_inputs(
    generators: &[Option<mbd_dataset::ProfileGenerator>],
    designs: &[mbd_system::Sampled],
) -> Vec<SampleInput> {
    (0..designs.len() as u64)
        .map(|id| SampleInput {
            id,
            params: designs[id as usize].clone(),
            profiles: generators
                .iter()
                .map(|g| {
                    g.as_ref().map(|g| {
                        Profile::new(g.positions(), g.profile(id))
                            .expect("generated profiles are valid")
                    })
                })
                .collect(),
        })
        .collect()
}

/// What the runs of a synthetic dataset are written and weighed with.
struct Simulation<'a> {
    system: &'a Arc<mbd_system::System>,
    units: &'a Units,
    plan: &'a SamplingPlan,
    designs: &'a [mbd_system::Sampled],
    layout: &'a Layout,
    weights: WeightConfig,
    /// The records' time step (s).
    record_dt: f64,
}

impl Simulation<'_> {
    /// Runs `engines` into `simulation.parquet` at `path` and returns the magnitude weights
    /// phi of the training samples, by id (`dir`: the dataset's, for errors).
    fn run(
        &self,
        engines: &[(u64, mbd_engine::Engine)],
        path: &Path,
        dir: &Path,
    ) -> Result<Vec<(i64, Vec<f64>)>> {
        let bad = |message: String| dataset_error(dir, message);
        let system = self.system;
        let mut cols = vec![schema::SAMPLE_ID.to_owned(), schema::TIME.to_owned()];
        cols.extend(system.channels.iter().map(|c| c.name.clone()));
        let weight_idx: Vec<usize> = pino_learn::weights::columns(self.layout)
            .iter()
            .map(|c| system.channel(c).expect("a stored channel"))
            .collect();
        let mut writer: Option<StreamWriter> = None;
        let mut phi: Vec<(i64, Vec<f64>)> = Vec::new();
        // 64 samples at a time in parallel, written in id order (one row group per sample).
        mbd_engine::run_all(engines, 64, &|| {}, |id, out| -> Result<()> {
            let tr = out.map_err(|f| bad(format!("sample {id}: {}", f.reason)))?;
            let mut t = Table::default().with_units(self.units.clone());
            t.push(&cols[0], Column::I64(vec![id as i64; tr.t.len()]))?;
            t.push(&cols[1], Column::F64(tr.t.clone()))?;
            for (name, col) in cols[2..].iter().zip(&tr.columns) {
                t.push(name, Column::F64(col.clone()))?;
            }
            let w = match &mut writer {
                Some(w) => w,
                None => writer.insert(StreamWriter::create(path, &t)?),
            };
            w.write(&t)?;
            if self.plan.split(id) == mbd_dataset::Split::Train && !self.layout.equations.is_empty()
            {
                let record: Vec<Vec<f64>> =
                    weight_idx.iter().map(|&c| tr.columns[c].clone()).collect();
                let p = magnitude_weights(
                    &self.weights,
                    system,
                    self.layout,
                    &self.designs[id as usize],
                    id,
                    &record,
                    self.record_dt,
                )?;
                phi.push((id as i64, p));
            }
            Ok(())
        })?;
        writer.ok_or_else(|| bad("no samples".into()))?.finish()?;
        Ok(phi)
    }
}
