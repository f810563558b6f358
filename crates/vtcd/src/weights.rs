//! ODE magnitude weights of PINO-MBD (`docs/model.md`, ODE residuals and magnitude weights;
//! `docs/learning.md`, phi).
//!
//! For one sample `k` and vehicle equation `i` (DOF order `z_c, beta_c, z_t1, beta_t1, z_t2,
//! beta_t2, z_w1..z_w4`):
//! ```text
//! phi_ki = max_t |R_i(t)|                  (N or N m)
//! R      = M a~ - F(z~, v~, P~)            (Vehicle::residuals)
//! s~     = s + r std(s) xi,  xi ~ N(0, 1)  for every signal s below, every time point
//! P~_j   = Hertz(z~_wj - z~_rj - eta_j),  G = 4.57 R^-0.149 1e-8 m/N^(2/3)
//! ```
//! `std(s)` is the population standard deviation of the signal over the evaluated window of
//! this sample. The window drops the first `window_start_fraction` of the record (default 0.1,
//! the start-up part that training also drops), so `phi` measures the same part of the record
//! the weighted ODE loss sees.
//!
//! **Noise order** (fixed; it makes `phi` reproducible from the seed): the normals of
//! `SampleStream::new(seed, Purpose::WeightNoise, sample_id)` are consumed signal by signal in
//! the column order of the simulation file, `z_c..z_w4` (10 displacements), `z_r1..z_r4`,
//! the ten `_v`, the ten `_a`, and within a signal in time order over the window. Every signal
//! consumes its normals even when its std is 0. `eta` is an input, not a solution: it is not
//! noised.
//!
//! Units: displacements m, angles rad, velocities m/s or rad/s, accelerations m/s^2 or
//! rad/s^2, positive downward / nose-up as in [`crate::vehicle`].

use crate::contact::{contact_force, hertz_constant};
use crate::params::SampleParams;
use crate::rng::{Purpose, SampleStream};
use crate::vehicle::{Vehicle, FIRST_WHEEL, NUM_DOFS};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Default noise ratio `r` (spec: 2%).
pub const DEFAULT_NOISE_RATIO: f64 = 0.02;
/// Default gravity (m/s^2).
pub const DEFAULT_GRAVITY: f64 = 9.81;
/// Default wheel radius (m).
pub const DEFAULT_WHEEL_RADIUS: f64 = 0.43;
/// Default fraction of the record dropped before evaluating (the start-up, as in training).
pub const DEFAULT_WINDOW_START_FRACTION: f64 = 0.1;

/// Number of noised signals: 10 displacements, 4 rail, 10 velocities, 10 accelerations.
pub const NUM_NOISED_SIGNALS: usize = 3 * NUM_DOFS + 4;

/// The weights configuration as written in the pipeline (unchecked); defaults from the spec.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightParams {
    /// Seed of the noise streams.
    pub seed: u64,
    /// Noise ratio `r` in (0, 1]; default 0.02.
    #[serde(default = "default_noise_ratio")]
    pub noise_ratio: f64,
    /// Gravity `g` (m/s^2) of the static wheel load; default 9.81.
    #[serde(default = "default_gravity")]
    pub gravity: f64,
    /// Wheel radius `R` (m) of the Hertz constant; default 0.43.
    #[serde(default = "default_wheel_radius")]
    pub wheel_radius: f64,
    /// Fraction of each record dropped before evaluating, in [0, 1); default 0.1.
    #[serde(default = "default_window_start_fraction")]
    pub window_start_fraction: f64,
}

fn default_noise_ratio() -> f64 {
    DEFAULT_NOISE_RATIO
}
fn default_gravity() -> f64 {
    DEFAULT_GRAVITY
}
fn default_wheel_radius() -> f64 {
    DEFAULT_WHEEL_RADIUS
}
fn default_window_start_fraction() -> f64 {
    DEFAULT_WINDOW_START_FRACTION
}

impl WeightParams {
    /// Checks the ranges (see [`WeightConfig::new`]).
    pub fn validate(&self) -> Result<WeightConfig> {
        WeightConfig::new(
            self.seed,
            self.noise_ratio,
            self.gravity,
            self.wheel_radius,
            self.window_start_fraction,
        )
    }
}

/// A checked weights configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeightConfig {
    seed: u64,
    noise_ratio: f64,
    gravity: f64,
    wheel_radius: f64,
    window_start_fraction: f64,
}

impl WeightConfig {
    /// Checks `noise_ratio` in (0, 1], `gravity > 0`, `wheel_radius > 0`,
    /// `window_start_fraction` in [0, 1).
    pub fn new(
        seed: u64,
        noise_ratio: f64,
        gravity: f64,
        wheel_radius: f64,
        window_start_fraction: f64,
    ) -> Result<Self> {
        let check = |name: &str, value: f64, ok: bool, allowed: &str| {
            if ok {
                Ok(())
            } else {
                Err(Error::OutOfRange {
                    name: name.to_owned(),
                    value,
                    allowed: allowed.to_owned(),
                })
            }
        };
        check(
            "noise_ratio",
            noise_ratio,
            noise_ratio > 0.0 && noise_ratio <= 1.0,
            "in (0, 1]",
        )?;
        check(
            "gravity",
            gravity,
            gravity.is_finite() && gravity > 0.0,
            "finite and > 0 (m/s^2)",
        )?;
        check(
            "wheel_radius",
            wheel_radius,
            wheel_radius.is_finite() && wheel_radius > 0.0,
            "finite and > 0 (m)",
        )?;
        check(
            "window_start_fraction",
            window_start_fraction,
            (0.0..1.0).contains(&window_start_fraction),
            "in [0, 1)",
        )?;
        Ok(Self {
            seed,
            noise_ratio,
            gravity,
            wheel_radius,
            window_start_fraction,
        })
    }

    /// The spec defaults (r = 2%, g = 9.81, R = 0.43, window from 10%) with seed `seed`.
    pub fn with_seed(seed: u64) -> Self {
        Self {
            seed,
            noise_ratio: DEFAULT_NOISE_RATIO,
            gravity: DEFAULT_GRAVITY,
            wheel_radius: DEFAULT_WHEEL_RADIUS,
            window_start_fraction: DEFAULT_WINDOW_START_FRACTION,
        }
    }

    /// First evaluated index of a record of `len` points: `floor(fraction len)`.
    pub fn window_start(&self, len: usize) -> usize {
        (self.window_start_fraction * len as f64).floor() as usize
    }
}

/// One sample's stored solution, every slice the same length (time order).
#[derive(Debug, Clone, Copy)]
pub struct SampleSignals<'a> {
    /// Vehicle displacements in DOF order (m or rad).
    pub z: [&'a [f64]; NUM_DOFS],
    /// Vehicle velocities (`_v`).
    pub v: [&'a [f64]; NUM_DOFS],
    /// Vehicle accelerations (`_a`).
    pub a: [&'a [f64]; NUM_DOFS],
    /// Rail displacement under each wheel `z_r1..z_r4` (m).
    pub z_r: [&'a [f64]; 4],
    /// Irregularity under each wheel `eta_1..eta_4` (m).
    pub eta: [&'a [f64]; 4],
}

impl SampleSignals<'_> {
    /// Common length; an error naming the first signal that differs.
    pub fn common_len(&self) -> Result<usize> {
        let n = self.z[0].len();
        let all = self
            .z
            .iter()
            .chain(&self.z_r)
            .chain(&self.v)
            .chain(&self.a)
            .chain(&self.eta);
        for (j, s) in all.enumerate() {
            if s.len() != n {
                return Err(Error::Shape {
                    name: signal_name(j),
                    found: s.len(),
                    expected: n,
                });
            }
        }
        Ok(n)
    }
}

const DOF_NAMES: [&str; NUM_DOFS] = [
    "z_c", "beta_c", "z_t1", "beta_t1", "z_t2", "beta_t2", "z_w1", "z_w2", "z_w3", "z_w4",
];

/// Name of signal `j` in noise order (then `eta_1..eta_4`), for messages.
fn signal_name(j: usize) -> String {
    match j {
        0..10 => DOF_NAMES[j].to_owned(),
        10..14 => format!("z_r{}", j - 9),
        14..24 => format!("{}_v", DOF_NAMES[j - 14]),
        24..34 => format!("{}_a", DOF_NAMES[j - 24]),
        _ => format!("eta_{}", j - 33),
    }
}

/// `max_t |R_i|` of the signals as given (no noise), over `start..len`.
pub fn max_abs_residuals(
    vehicle: &Vehicle,
    hertz_g: f64,
    s: &SampleSignals<'_>,
    start: usize,
) -> Result<[f64; NUM_DOFS]> {
    let n = s.common_len()?;
    let mut max = [0.0f64; NUM_DOFS];
    for t in start..n {
        let z: [f64; NUM_DOFS] = std::array::from_fn(|i| s.z[i][t]);
        let v: [f64; NUM_DOFS] = std::array::from_fn(|i| s.v[i][t]);
        let a: [f64; NUM_DOFS] = std::array::from_fn(|i| s.a[i][t]);
        // Hertz with the (possibly noised) wheel and rail displacements.
        let p: [f64; 4] = std::array::from_fn(|j| {
            contact_force(z[FIRST_WHEEL + j] - s.z_r[j][t] - s.eta[j][t], hertz_g)
        });
        let r = vehicle.residuals(&z, &v, &a, &p);
        for (m, ri) in max.iter_mut().zip(r) {
            // f64::max drops NaN: keep a NaN once seen so that bad data cannot hide.
            *m = if m.is_nan() || ri.is_nan() {
                f64::NAN
            } else {
                m.max(ri.abs())
            };
        }
    }
    Ok(max)
}

/// `phi_ki` of sample `sample_id` with parameters `params`: noise as in the module doc, then
/// [`max_abs_residuals`] over the window. Needs at least one point in the window.
pub fn magnitude_weights(
    cfg: &WeightConfig,
    params: &SampleParams,
    sample_id: u64,
    s: &SampleSignals<'_>,
) -> Result<[f64; NUM_DOFS]> {
    let n = s.common_len()?;
    let start = cfg.window_start(n);
    if start >= n {
        return Err(Error::Shape {
            name: "record".to_owned(),
            found: n,
            expected: start + 1,
        });
    }
    let mut stream = SampleStream::new(cfg.seed, Purpose::WeightNoise, sample_id);
    let sources = s.z.iter().chain(&s.z_r).chain(&s.v).chain(&s.a);
    let noised: Vec<Vec<f64>> = sources
        .map(|sig| {
            let w = &sig[start..];
            let m = w.len() as f64;
            let mean = w.iter().sum::<f64>() / m;
            let std = (w.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / m).sqrt();
            let sd = cfg.noise_ratio * std;
            w.iter().map(|x| x + sd * stream.normal()).collect()
        })
        .collect();
    let eta: [&[f64]; 4] = std::array::from_fn(|j| &s.eta[j][start..]);
    let view = SampleSignals {
        z: std::array::from_fn(|i| noised[i].as_slice()),
        z_r: std::array::from_fn(|j| noised[NUM_DOFS + j].as_slice()),
        v: std::array::from_fn(|i| noised[NUM_DOFS + 4 + i].as_slice()),
        a: std::array::from_fn(|i| noised[2 * NUM_DOFS + 4 + i].as_slice()),
        eta,
    };
    let vehicle = Vehicle::new(params, cfg.gravity);
    let phi = max_abs_residuals(&vehicle, hertz_constant(cfg.wheel_radius), &view, 0)?;
    if let Some(i) = phi.iter().position(|x| !x.is_finite()) {
        return Err(Error::OutOfRange {
            name: format!("phi_{} of sample {sample_id}", i + 1),
            value: phi[i],
            allowed: "finite (the record holds non-finite values)".to_owned(),
        });
    }
    Ok(phi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::static_compression;

    /// A consistent record: smooth displacements and velocities, rail and irregularity
    /// signals, contact forces from Hertz and accelerations from the equations of motion, so
    /// every residual vanishes to round-off.
    struct Record {
        z: Vec<Vec<f64>>,
        v: Vec<Vec<f64>>,
        a: Vec<Vec<f64>>,
        z_r: Vec<Vec<f64>>,
        eta: Vec<Vec<f64>>,
    }

    impl Record {
        fn consistent(p: &SampleParams, n: usize) -> Self {
            let veh = Vehicle::new(p, DEFAULT_GRAVITY);
            let g = hertz_constant(DEFAULT_WHEEL_RADIUS);
            let d0 = static_compression(veh.w, g);
            let mut r = Record {
                z: vec![vec![0.0; n]; NUM_DOFS],
                v: vec![vec![0.0; n]; NUM_DOFS],
                a: vec![vec![0.0; n]; NUM_DOFS],
                z_r: vec![vec![0.0; n]; 4],
                eta: vec![vec![0.0; n]; 4],
            };
            for t in 0..n {
                let tt = t as f64 * 1e-3;
                let z: [f64; NUM_DOFS] = std::array::from_fn(|i| {
                    let amp = if i % 2 == 1 && i < FIRST_WHEEL {
                        1e-4
                    } else {
                        1e-3
                    };
                    let base = if i >= FIRST_WHEEL { d0 + 2e-4 } else { 0.0 };
                    base + amp * (7.0 * tt + i as f64).sin()
                });
                let v: [f64; NUM_DOFS] =
                    std::array::from_fn(|i| 1e-2 * (5.0 * tt + 0.3 * i as f64).cos());
                let mut p = [0.0; 4];
                for j in 0..4 {
                    r.z_r[j][t] = 2e-4 + 1e-4 * (11.0 * tt + j as f64).sin();
                    r.eta[j][t] = 3e-4 * (13.0 * tt + 2.0 * j as f64).cos();
                    p[j] = contact_force(z[FIRST_WHEEL + j] - r.z_r[j][t] - r.eta[j][t], g);
                }
                let a = veh.accelerations(&z, &v, &p);
                for i in 0..NUM_DOFS {
                    r.z[i][t] = z[i];
                    r.v[i][t] = v[i];
                    r.a[i][t] = a[i];
                }
            }
            r
        }

        fn signals(&self) -> SampleSignals<'_> {
            SampleSignals {
                z: std::array::from_fn(|i| self.z[i].as_slice()),
                v: std::array::from_fn(|i| self.v[i].as_slice()),
                a: std::array::from_fn(|i| self.a[i].as_slice()),
                z_r: std::array::from_fn(|j| self.z_r[j].as_slice()),
                eta: std::array::from_fn(|j| self.eta[j].as_slice()),
            }
        }
    }

    fn cfg(seed: u64, r: f64, start: f64) -> WeightConfig {
        WeightConfig::new(seed, r, DEFAULT_GRAVITY, DEFAULT_WHEEL_RADIUS, start).unwrap()
    }

    #[test]
    fn tiny_noise_gives_the_clean_residual_which_vanishes_on_consistent_data() {
        let p = SampleParams::NOMINAL;
        let rec = Record::consistent(&p, 300);
        let veh = Vehicle::new(&p, DEFAULT_GRAVITY);
        let clean = max_abs_residuals(&veh, hertz_constant(0.43), &rec.signals(), 0).unwrap();
        // Round-off of forces ~ W = 7e4 N: 1e-9 W is far below any noised value below.
        assert!(clean.iter().all(|r| *r < 1e-9 * veh.w), "{clean:?}");
        let phi = magnitude_weights(&cfg(1, 1e-12, 0.0), &p, 0, &rec.signals()).unwrap();
        // r = 1e-12: the noise moves each residual by ~1e-12 of its force scale (< 1e-5 N).
        assert!(phi.iter().all(|x| *x < 1e-5), "{phi:?}");
        // r = 2%: every equation has a clearly nonzero weight, wheels of the order of the
        // Hertz force change 1.5 W^(1/3)/G * 2% of the wheel displacement std (~ 1e4 N).
        let phi = magnitude_weights(&cfg(1, 0.02, 0.0), &p, 0, &rec.signals()).unwrap();
        assert!(phi.iter().all(|x| *x > 1.0), "{phi:?}");
        // Halving r roughly halves phi in the linear equations (body and bogies).
        let half = magnitude_weights(&cfg(1, 0.01, 0.0), &p, 0, &rec.signals()).unwrap();
        for i in 0..FIRST_WHEEL {
            assert!(
                (half[i] / phi[i] - 0.5).abs() < 1e-9,
                "{i}: {} vs {}",
                half[i],
                phi[i]
            );
        }
    }

    #[test]
    fn hand_computed_two_point_case() {
        // Every signal zero except z_c = [d, -d] (std d): only z_c is noised, by r d xi_t
        // with xi_0, xi_1 the first two normals of the stream. Then, with wheels unloaded
        // (delta = 0 -> P = 0):
        //   R_1 = -F_1 = 2 k_s z_c,  R_3 = R_5 = -k_s z_c,  R_2 = R_4 = R_6 = 0,  R_wheel = -W.
        let p = SampleParams::NOMINAL;
        let (d, r, seed, id) = (1e-3, 0.1, 42, 17);
        let n = 2;
        let zero = vec![0.0; n];
        let zc = vec![d, -d];
        let mut z: [&[f64]; NUM_DOFS] = [&zero; NUM_DOFS];
        z[0] = &zc;
        let s = SampleSignals {
            z,
            v: [&zero; NUM_DOFS],
            a: [&zero; NUM_DOFS],
            z_r: [&zero; 4],
            eta: [&zero; 4],
        };
        let phi = magnitude_weights(&cfg(seed, r, 0.0), &p, id, &s).unwrap();
        let mut stream = SampleStream::new(seed, Purpose::WeightNoise, id);
        let (x0, x1) = (stream.normal(), stream.normal());
        let zmax = (d + r * d * x0).abs().max((-d + r * d * x1).abs());
        let w = Vehicle::new(&p, DEFAULT_GRAVITY).w;
        let expected = [
            2.0 * p.k_s * zmax,
            0.0,
            p.k_s * zmax,
            0.0,
            p.k_s * zmax,
            0.0,
            w,
            w,
            w,
            w,
        ];
        for i in 0..NUM_DOFS {
            // Two products and a sum: round-off 1e-12 relative.
            assert!(
                (phi[i] - expected[i]).abs() <= 1e-12 * expected[i].abs().max(1.0),
                "{i}: {} vs {}",
                phi[i],
                expected[i]
            );
        }
    }

    #[test]
    fn window_drops_the_start() {
        // A spike in z_c in the first 10% of the record does not enter phi with the default
        // window, and enters it with window_start_fraction = 0.
        let p = SampleParams::NOMINAL;
        let mut rec = Record::consistent(&p, 100);
        rec.a[0][3] += 1.0; // residual R_1 jumps by m_c * 1 at t = 3
        let m_c = p.m_c / 2.0;
        let full = magnitude_weights(&cfg(1, 1e-12, 0.0), &p, 0, &rec.signals()).unwrap();
        assert!((full[0] - m_c).abs() < 1e-6 * m_c, "{}", full[0]);
        let windowed = magnitude_weights(&cfg(1, 1e-12, 0.1), &p, 0, &rec.signals()).unwrap();
        assert!(windowed[0] < 1e-5, "{}", windowed[0]);
    }

    #[test]
    fn reproducible_from_the_seed() {
        let p = SampleParams::NOMINAL;
        let rec = Record::consistent(&p, 200);
        let a = magnitude_weights(&cfg(7, 0.02, 0.1), &p, 3, &rec.signals()).unwrap();
        let b = magnitude_weights(&cfg(7, 0.02, 0.1), &p, 3, &rec.signals()).unwrap();
        assert_eq!(a, b);
        let c = magnitude_weights(&cfg(8, 0.02, 0.1), &p, 3, &rec.signals()).unwrap();
        let d = magnitude_weights(&cfg(7, 0.02, 0.1), &p, 4, &rec.signals()).unwrap();
        assert_ne!(a, c);
        assert_ne!(a, d);
    }

    #[test]
    fn bad_input_is_named() {
        let e = WeightConfig::new(1, 0.0, 9.81, 0.43, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`noise_ratio`") && e.contains("(0, 1]"), "{e}");
        let e = WeightConfig::new(1, 1.5, 9.81, 0.43, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`noise_ratio` = 1.5"), "{e}");
        let e = WeightConfig::new(1, 0.02, -9.81, 0.43, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`gravity`"), "{e}");
        let e = WeightConfig::new(1, 0.02, 9.81, 0.0, 0.1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`wheel_radius`"), "{e}");
        let e = WeightConfig::new(1, 0.02, 9.81, 0.43, 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`window_start_fraction`") && e.contains("[0, 1)"),
            "{e}"
        );
        // Mismatched lengths name the signal.
        let p = SampleParams::NOMINAL;
        let rec = Record::consistent(&p, 50);
        let mut s = rec.signals();
        s.a[3] = &rec.a[3][..49];
        let e = magnitude_weights(&cfg(1, 0.02, 0.1), &p, 0, &s)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`beta_t1_a` has 49 points, expected 50"), "{e}");
        let empty: [&[f64]; 4] = [&[]; 4];
        let s = SampleSignals {
            z: [&[]; NUM_DOFS],
            v: [&[]; NUM_DOFS],
            a: [&[]; NUM_DOFS],
            z_r: empty,
            eta: empty,
        };
        assert!(magnitude_weights(&cfg(1, 0.02, 0.1), &p, 0, &s).is_err());
        // A NaN anywhere in the window is refused, even when later points are finite.
        let mut rec = Record::consistent(&p, 50);
        rec.v[2][10] = f64::NAN;
        let e = magnitude_weights(&cfg(1, 0.02, 0.1), &p, 9, &rec.signals())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("phi_") && e.contains("of sample 9") && e.contains("finite"),
            "{e}"
        );
    }
}
