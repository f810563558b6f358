//! Small, exactly consistent datasets for tests and benchmarks (not the paper's physics: the
//! rail is rigid, `z_r = 0`).
//!
//! Each sample draws its 14 parameters uniformly on the spec's ranges and a smooth
//! irregularity profile `eta(x) = sum_j A_j sin(2 pi x / lambda_j + phase_j)` (three
//! wavelengths in [10, 40] m), faded in with a smoothstep over the first 20% of the record.
//! Wheel `i` reads the profile at `x_i(t) = 20 + l_c + l_t + v t + offset_i` with offsets
//! `(l_c + l_t, l_c - l_t, -l_c + l_t, -l_c - l_t)`. The 10-DOF vehicle of `vtcd::vehicle` with
//! Hertz contact on the rigid rail starts at its static equilibrium (every vertical DOF at the
//! static contact compression `G W^(2/3)`) and is integrated with classical RK4 at
//! `dt_out / substeps`; at each stored time the record holds the state `z, v` and
//! `a = M^-1 F(z, v, P)` evaluated there, so the stored triple satisfies the ODEs to rounding.
//!
//! Files written (the physics stages' contract): `params.parquet`, `simulation.parquet`,
//! `weights.parquet` (phi from the definition in `docs/learning.md` with noise ratio `r`).

use crate::Result;
use pino_data::{schema, write_parquet, Column, StreamWriter, Table};
use std::path::{Path, PathBuf};
use vtcd::contact::{contact_force, hertz_constant, static_compression};
use vtcd::params::SampleParams;
use vtcd::rng::{Purpose, SampleStream};
use vtcd::vehicle::{Vehicle, NUM_DOFS};

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyntheticSpec {
    /// Training samples (ids `0..n_train`).
    pub n_train: usize,
    /// Validation samples (the following ids).
    pub n_validation: usize,
    /// Test samples (the ids after validation).
    pub n_test: usize,
    /// Record duration (s).
    pub duration: f64,
    /// Output spacing (s).
    pub dt_out: f64,
    /// RK4 steps per output step.
    pub substeps: usize,
    /// Irregularity amplitude scale (m).
    pub amplitude: f64,
    /// Seed.
    pub seed: u64,
    /// Noise ratio of the ODE magnitude weights.
    pub noise_ratio: f64,
}

impl Default for SyntheticSpec {
    fn default() -> Self {
        Self {
            n_train: 8,
            n_validation: 2,
            n_test: 0,
            duration: 0.3,
            dt_out: 1e-3,
            substeps: 10,
            amplitude: 1e-3,
            seed: 1,
            noise_ratio: 0.02,
        }
    }
}

/// One simulated record: rows of `(t, z[10], v[10], a[10], eta[4], p[4])`.
#[derive(Debug, Clone)]
pub struct Record {
    /// Times (s).
    pub t: Vec<f64>,
    /// Displacements per time.
    pub z: Vec<[f64; NUM_DOFS]>,
    /// Velocities per time.
    pub v: Vec<[f64; NUM_DOFS]>,
    /// Accelerations per time.
    pub a: Vec<[f64; NUM_DOFS]>,
    /// Irregularity under each wheel.
    pub eta: Vec<[f64; 4]>,
    /// Contact forces.
    pub p: Vec<[f64; 4]>,
}

/// Parameters of sample `id`: uniform on the spec's ranges.
pub fn sample_params(seed: u64, id: u64) -> SampleParams {
    let mut s = SampleStream::new(seed, Purpose::Parameters, id);
    let nominal = SampleParams::NOMINAL.to_array();
    let mut a = [0.0; 14];
    for k in 0..11 {
        a[k] = nominal[k] * s.uniform_in(0.8, 1.2);
    }
    a[11] = s.uniform_in(300.0, 350.0);
    a[12] = s.uniform_in(3.5e7, 4.5e7);
    a[13] = s.uniform_in(4e4, 5e4);
    SampleParams::from_array(a)
}

/// Integrates one sample.
pub fn simulate(p: &SampleParams, spec: &SyntheticSpec, id: u64) -> Record {
    let g = 9.81;
    let hertz = hertz_constant(0.43);
    let veh = Vehicle::new(p, g);
    let mut s = SampleStream::new(spec.seed, Purpose::Irregularity, id);
    let waves: Vec<(f64, f64, f64)> = (0..3)
        .map(|_| {
            let lambda = s.uniform_in(10.0, 40.0);
            let amp = spec.amplitude * s.uniform_in(0.2, 0.5);
            let phase = s.uniform_in(0.0, 2.0 * std::f64::consts::PI);
            (lambda, amp, phase)
        })
        .collect();
    let speed = p.speed();
    let offsets = [p.l_c + p.l_t, p.l_c - p.l_t, -p.l_c + p.l_t, -p.l_c - p.l_t];
    let fade = 0.2 * spec.duration;
    let eta = |t: f64| -> [f64; 4] {
        let x = (t / fade).clamp(0.0, 1.0);
        let ramp = x * x * (3.0 - 2.0 * x);
        std::array::from_fn(|i| {
            let xi = 20.0 + p.l_c + p.l_t + speed * t + offsets[i];
            ramp * waves
                .iter()
                .map(|(l, a, ph)| a * (2.0 * std::f64::consts::PI * xi / l + ph).sin())
                .sum::<f64>()
        })
    };
    let contact = |z: &[f64; NUM_DOFS], t: f64| -> [f64; 4] {
        let e = eta(t);
        std::array::from_fn(|i| contact_force(z[6 + i] - e[i], hertz))
    };
    let accel =
        |z: &[f64; NUM_DOFS], v: &[f64; NUM_DOFS], t: f64| veh.accelerations(z, v, &contact(z, t));
    let d0 = static_compression(veh.w, hertz);
    let mut z = [0.0; NUM_DOFS];
    for i in [0, 2, 4, 6, 7, 8, 9] {
        z[i] = d0;
    }
    let mut v = [0.0; NUM_DOFS];
    let n_out = (spec.duration / spec.dt_out).round() as usize;
    let h = spec.dt_out / spec.substeps as f64;
    let mut rec = Record {
        t: Vec::with_capacity(n_out),
        z: Vec::with_capacity(n_out),
        v: Vec::with_capacity(n_out),
        a: Vec::with_capacity(n_out),
        eta: Vec::with_capacity(n_out),
        p: Vec::with_capacity(n_out),
    };
    let add = |x: &[f64; NUM_DOFS], k: &[f64; NUM_DOFS], f: f64| -> [f64; NUM_DOFS] {
        std::array::from_fn(|i| x[i] + f * k[i])
    };
    for n in 0..n_out {
        let t = n as f64 * spec.dt_out;
        rec.t.push(t);
        rec.z.push(z);
        rec.v.push(v);
        rec.a.push(accel(&z, &v, t));
        rec.eta.push(eta(t));
        rec.p.push(contact(&z, t));
        for k in 0..spec.substeps {
            let tk = t + k as f64 * h;
            // Classical RK4 on (z, v): z' = v, v' = a(z, v, t).
            let a1 = accel(&z, &v, tk);
            let (z2, v2) = (add(&z, &v, h / 2.0), add(&v, &a1, h / 2.0));
            let a2 = accel(&z2, &v2, tk + h / 2.0);
            let (z3, v3) = (add(&z, &v2, h / 2.0), add(&v, &a2, h / 2.0));
            let a3 = accel(&z3, &v3, tk + h / 2.0);
            let (z4, v4) = (add(&z, &v3, h), add(&v, &a3, h));
            let a4 = accel(&z4, &v4, tk + h);
            for i in 0..NUM_DOFS {
                z[i] += h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i]);
                v[i] += h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i]);
            }
        }
    }
    rec
}

/// ODE magnitude weights of a record: noise of `r` times each signal's std added to every
/// displacement, velocity and acceleration (and the zero rail), phi_i = max_t |R_i|.
pub fn phi(p: &SampleParams, rec: &Record, r: f64, seed: u64, id: u64) -> [f64; NUM_DOFS] {
    let veh = Vehicle::new(p, 9.81);
    let hertz = hertz_constant(0.43);
    let mut s = SampleStream::new(seed, Purpose::WeightNoise, id);
    let std_of = |f: &dyn Fn(usize) -> f64| -> f64 {
        let n = rec.t.len() as f64;
        let m = (0..rec.t.len()).map(f).sum::<f64>() / n;
        ((0..rec.t.len()).map(|k| (f(k) - m).powi(2)).sum::<f64>() / n).sqrt()
    };
    let sz: [f64; NUM_DOFS] = std::array::from_fn(|i| std_of(&|k| rec.z[k][i]));
    let sv: [f64; NUM_DOFS] = std::array::from_fn(|i| std_of(&|k| rec.v[k][i]));
    let sa: [f64; NUM_DOFS] = std::array::from_fn(|i| std_of(&|k| rec.a[k][i]));
    let mut out = [0.0f64; NUM_DOFS];
    for k in 0..rec.t.len() {
        let z: [f64; NUM_DOFS] = std::array::from_fn(|i| rec.z[k][i] + r * sz[i] * s.normal());
        let v: [f64; NUM_DOFS] = std::array::from_fn(|i| rec.v[k][i] + r * sv[i] * s.normal());
        let a: [f64; NUM_DOFS] = std::array::from_fn(|i| rec.a[k][i] + r * sa[i] * s.normal());
        let pc: [f64; 4] = std::array::from_fn(|i| contact_force(z[6 + i] - rec.eta[k][i], hertz));
        let res = veh.residuals(&z, &v, &a, &pc);
        for i in 0..NUM_DOFS {
            out[i] = out[i].max(res[i].abs());
        }
    }
    out
}

/// Paths of a generated dataset.
#[derive(Debug, Clone)]
pub struct SyntheticFiles {
    /// `params.parquet`.
    pub params: PathBuf,
    /// `simulation.parquet`.
    pub simulation: PathBuf,
    /// `weights.parquet`.
    pub weights: PathBuf,
}

/// Generates and writes a dataset into `dir`. The simulation is written one row group per
/// sample (as the `simulate` stage does), generated 64 samples at a time in parallel, so
/// large benchmark datasets need little memory.
pub fn write_dataset(spec: &SyntheticSpec, dir: &Path) -> Result<SyntheticFiles> {
    use rayon::prelude::*;
    let n = spec.n_train + spec.n_validation + spec.n_test;
    let params: Vec<SampleParams> = (0..n as u64)
        .map(|id| sample_params(spec.seed, id))
        .collect();
    let mut pt = Table::default();
    pt.push(schema::SAMPLE_ID, Column::I64((0..n as i64).collect()))?;
    pt.push(
        schema::SPLIT,
        Column::Str(
            (0..n)
                .map(|i| {
                    if i < spec.n_train {
                        schema::SPLIT_TRAIN
                    } else if i < spec.n_train + spec.n_validation {
                        schema::SPLIT_VALIDATION
                    } else {
                        schema::SPLIT_TEST
                    }
                    .to_owned()
                })
                .collect(),
        ),
    )?;
    for (k, name) in schema::PARAMETERS.iter().enumerate() {
        pt.push(
            name,
            Column::F64(params.iter().map(|p| p.to_array()[k]).collect()),
        )?;
    }
    let files = SyntheticFiles {
        params: dir.join("params.parquet"),
        simulation: dir.join("simulation.parquet"),
        weights: dir.join("weights.parquet"),
    };
    write_parquet(&files.params, &pt)?;
    // The constants the records below are consistent with (checked by `weights` and `train`).
    pino_data::provenance::write_provenance(
        &dir.join(pino_data::provenance::PROVENANCE_FILE),
        &[
            ("gravity", vtcd::weights::DEFAULT_GRAVITY),
            ("wheel_radius", vtcd::weights::DEFAULT_WHEEL_RADIUS),
        ],
    )?;

    let table_of = |id: usize, r: &Record| -> Result<Table> {
        let mut st = Table::default();
        let col = |f: &dyn Fn(usize) -> f64| Column::F64((0..r.t.len()).map(f).collect());
        st.push(schema::SAMPLE_ID, Column::I64(vec![id as i64; r.t.len()]))?;
        st.push(schema::TIME, col(&|k| r.t[k]))?;
        for (i, name) in schema::VEHICLE_DOFS.iter().enumerate() {
            st.push(name, col(&|k| r.z[k][i]))?;
        }
        for name in schema::RAIL_UNDER_WHEEL {
            st.push(name, col(&|_| 0.0))?;
        }
        for (i, name) in schema::VEHICLE_DOFS.iter().enumerate() {
            st.push(&schema::velocity(name), col(&|k| r.v[k][i]))?;
        }
        for (i, name) in schema::VEHICLE_DOFS.iter().enumerate() {
            st.push(&schema::acceleration(name), col(&|k| r.a[k][i]))?;
        }
        for (i, name) in schema::ETA_UNDER_WHEEL.iter().enumerate() {
            st.push(name, col(&|k| r.eta[k][i]))?;
        }
        for (i, name) in schema::CONTACT_FORCES.iter().enumerate() {
            st.push(name, col(&|k| r.p[k][i]))?;
        }
        Ok(st)
    };
    let mut writer: Option<StreamWriter> = None;
    let mut phis: Vec<[f64; NUM_DOFS]> = Vec::with_capacity(n);
    for lo in (0..n).step_by(64) {
        let hi = (lo + 64).min(n);
        let chunk: Vec<(Table, [f64; NUM_DOFS])> = (lo..hi)
            .into_par_iter()
            .map(|id| {
                let p = &params[id];
                let rec = simulate(p, spec, id as u64);
                let phi = phi(p, &rec, spec.noise_ratio, spec.seed, id as u64);
                Ok((table_of(id, &rec)?, phi))
            })
            .collect::<Result<_>>()?;
        for (table, phi) in chunk {
            if writer.is_none() {
                writer = Some(StreamWriter::create(&files.simulation, &table)?);
            }
            writer.as_mut().expect("created").write(&table)?;
            phis.push(phi);
        }
    }
    if let Some(w) = writer {
        w.finish()?;
    }

    let mut wt = Table::default();
    wt.push(schema::SAMPLE_ID, Column::I64((0..n as i64).collect()))?;
    for (i, name) in schema::phi_columns().iter().enumerate() {
        wt.push(name, Column::F64(phis.iter().map(|p| p[i]).collect()))?;
    }
    write_parquet(&files.weights, &wt)?;
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_triples_satisfy_the_equations_and_rk4_is_accurate() {
        let spec = SyntheticSpec {
            duration: 0.2,
            ..Default::default()
        };
        let p = sample_params(1, 0);
        let rec = simulate(&p, &spec, 0);
        let veh = Vehicle::new(&p, 9.81);
        let g = hertz_constant(0.43);
        let mut max_r: f64 = 0.0;
        for k in 0..rec.t.len() {
            let pc: [f64; 4] =
                std::array::from_fn(|i| contact_force(rec.z[k][6 + i] - rec.eta[k][i], g));
            let r = veh.residuals(&rec.z[k], &rec.v[k], &rec.a[k], &pc);
            max_r = r.iter().fold(max_r, |m, x| m.max(x.abs()));
        }
        // Exact by construction: rounding of ~1e5 N forces, 1e-6 N.
        assert!(max_r < 1e-6, "{max_r}");
        // The stored velocity is the derivative of the stored displacement: central
        // differences agree to O(dt^2 z''') (a few percent of the velocity scale at worst).
        let w = 6;
        let vmax = rec.v.iter().map(|v| v[w].abs()).fold(0.0, f64::max);
        assert!(
            vmax > 1e-4,
            "the irregularity must excite the wheel: {vmax}"
        );
        for k in 1..rec.t.len() - 1 {
            let fd = (rec.z[k + 1][w] - rec.z[k - 1][w]) / (2.0 * spec.dt_out);
            assert!(
                (fd - rec.v[k][w]).abs() < 0.05 * vmax,
                "t {}: {fd} vs {}",
                rec.t[k],
                rec.v[k][w]
            );
        }
    }
}
