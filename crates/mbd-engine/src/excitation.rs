//! The excitations of a run without running it: the profile under every element that reads
//! one, `eta_e(t) = r(t) profile(x0 + v t + o_e)` (m, positive downward: a dip), with `v` the
//! frame speed, `o_e` the offset of the moving point the element rests on and `r` the start-up
//! factor of the run controls ([`RunConfig::ramp`]), and its rate `d eta_e / dt` (m/s, from the
//! profile's own interpolation). These are the values the engine's force evaluation reads at
//! the same `t`, so a learned operator (`predict`) sees the inputs the solver saw.

use crate::coverage::check_coverage;
use crate::engine::profile_sources;
use crate::{Profile, ProfileSource, Result, RunConfig};
use mbd_system::model::{Model, ModelEnd};
use mbd_system::system::Quantity;
use mbd_system::System;

/// The profiles under the elements of one sample's model for one run.
#[derive(Debug, Clone)]
pub struct Excitations {
    /// Per element: the profile it reads and the offset of its moving point (m).
    reads: Vec<Option<(usize, f64)>>,
    sources: Vec<ProfileSource>,
    speed: f64,
    config: RunConfig,
}

impl Excitations {
    /// The excitations of `model` (of `system`) under `config`, with `profiles[p]` the points
    /// of generated profile `p` (`None`: level). Refuses, as the engine does, a run that
    /// leaves a refusing beam or the profiles (the engine's own coverage check).
    pub fn new(
        system: &System,
        model: &Model,
        config: &RunConfig,
        profiles: Vec<Option<Profile>>,
    ) -> Result<Self> {
        config.validate()?;
        let sources = profile_sources(model, profiles)?;
        check_coverage(system, model, config, &sources)?;
        let reads = model
            .elements
            .iter()
            .map(|el| match (el.profile, el.to) {
                (Some(p), ModelEnd::Moving(pt)) => Some((p, model.points[pt].1)),
                _ => None,
            })
            .collect();
        Ok(Self {
            reads,
            sources,
            speed: model.speed,
            config: *config,
        })
    }

    /// Whether element `e` reads a profile.
    pub fn reads_profile(&self, e: usize) -> bool {
        self.reads[e].is_some()
    }

    /// The profile under element `e` at time `t` (m); 0 for an element that reads none.
    pub fn at(&self, e: usize, t: f64) -> f64 {
        match self.reads[e] {
            Some((p, offset)) => {
                let origin = self.config.x0 + self.speed * t;
                self.sources[p].ramped(self.config.ramp(t), origin + offset)
            }
            None => 0.0,
        }
    }

    /// The rate `d eta_e / dt` of the profile under element `e` at time `t` (m/s), as the
    /// engine evaluates it; 0 for an element that reads none.
    pub fn rate(&self, e: usize, t: f64) -> f64 {
        match self.reads[e] {
            Some((p, offset)) => {
                let origin = self.config.x0 + self.speed * t;
                let (ramp, ramp_rate) = (self.config.ramp(t), self.config.ramp_rate(t));
                self.sources[p].ramped_rate(ramp, ramp_rate, self.speed, origin + offset)
            }
            None => 0.0,
        }
    }

    /// The value at `t` of the excitation column holding `quantity`: a profile (m) or its
    /// rate (m/s); `None` for a quantity that is neither.
    pub fn column(&self, quantity: Quantity, t: f64) -> Option<f64> {
        match quantity {
            Quantity::Excitation(e) => Some(self.at(e, t)),
            Quantity::ExcitationRate(e) => Some(self.rate(e, t)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Engine, StartMode};
    use mbd_system::schema::Interpolation;
    use std::sync::Arc;

    const TEXT: &str = include_str!("../../../systems/quarter-car.yaml");

    /// The excitation columns of a run equal what `Excitations` computes at the stored times,
    /// bit for bit, through the start-up ramp and after it, with the road read linearly (the
    /// shipped quarter car) and by a cubic spline; with a damped tyre the road's rate too,
    /// which is the time derivative of the stored road (its own spline's slope).
    #[test]
    fn equals_the_engines_stored_excitation() {
        let band = "    wavelengths: [0.5, 90.0]";
        let tyre = "k: k_t, profile: road";
        assert_eq!(TEXT.matches(band).count(), 1);
        assert_eq!(TEXT.matches(tyre).count(), 1);
        let cubic = TEXT.replace(band, &format!("    interpolation: cubic\n{band}"));
        let damped = cubic.replace(tyre, "k: k_t, c: 300, profile: road");
        for (text, interpolation, rates) in [
            (TEXT, Interpolation::Linear, 0),
            (cubic.as_str(), Interpolation::Cubic, 0),
            (damped.as_str(), Interpolation::Cubic, 1),
        ] {
            equals_the_engines_stored_excitation_of(text, interpolation, rates);
        }
    }

    fn equals_the_engines_stored_excitation_of(
        text: &str,
        interpolation: Interpolation,
        rates: usize,
    ) {
        let system =
            Arc::new(mbd_system::load_str(text, "quarter-car.yaml", &Default::default()).unwrap());
        let model = system.instantiate(&system.nominal()).unwrap();
        assert_eq!(
            model.profiles,
            [mbd_system::model::ModelProfile::Generated { interpolation }]
        );
        let config = RunConfig {
            duration: 0.5,
            dt: 1e-4,
            output_every: 10,
            start: StartMode::Equilibrium,
            startup_zero_fraction: 0.1,
            startup_ramp_fraction: 0.2,
            x0: 3.0,
        };
        let x: Vec<f64> = (0..4000).map(|k| k as f64 * 0.05).collect();
        let eta: Vec<f64> = x
            .iter()
            .map(|x| 1e-3 * (0.7 * x).sin() + 1e-4 * x)
            .collect();
        let profiles: Vec<Option<Profile>> = system
            .profiles
            .iter()
            .map(|_| Some(Profile::new(x.clone(), eta.clone()).unwrap()))
            .collect();
        let engine = Engine::new(system.clone(), model.clone(), &config, profiles.clone()).unwrap();
        let run = engine.run().unwrap();
        let ex = Excitations::new(&system, &model, &config, profiles).unwrap();
        let mut checked = (0, 0);
        for (c, ch) in system.channels.iter().enumerate() {
            let (Quantity::Excitation(e) | Quantity::ExcitationRate(e)) = ch.quantity else {
                continue;
            };
            assert!(ex.reads_profile(e));
            for (k, &t) in run.t.iter().enumerate() {
                assert_eq!(
                    ex.column(ch.quantity, t),
                    Some(run.columns[c][k]),
                    "{} at t = {t}",
                    ch.name
                );
            }
            assert!(run.columns[c].iter().any(|v| *v != 0.0) && run.columns[c][0] == 0.0);
            if ch.quantity == Quantity::ExcitationRate(e) {
                is_the_time_derivative(&ex, &config, e, &run.t, &run.columns[c]);
                checked.1 += 1;
            } else {
                checked.0 += 1;
            }
        }
        assert_eq!(checked, (1, rates), "the quarter car stores its road input");
    }

    /// `rate` (stored at `times`) is the time derivative of the stored profile `ex.at(e, .)`:
    /// a central difference with a small step `h` (away from the ramp's kinks) agrees to 1e-6
    /// of the largest rate.
    fn is_the_time_derivative(
        ex: &Excitations,
        config: &RunConfig,
        e: usize,
        times: &[f64],
        rate: &[f64],
    ) {
        let h = 1e-6;
        let scale = rate.iter().fold(0.0f64, |m, r| m.max(r.abs()));
        let mut compared = 0;
        for (&t, &r) in times.iter().zip(rate) {
            if config.ramp_rate(t - h) != config.ramp_rate(t + h) {
                continue;
            }
            let difference = (ex.at(e, t + h) - ex.at(e, t - h)) / (2.0 * h);
            assert!(
                (difference - r).abs() <= 1e-6 * scale,
                "t = {t}: stored rate {r}, difference {difference}"
            );
            compared += 1;
        }
        assert!(compared + 2 >= times.len() && scale > 0.0);
    }

    /// A profile that ends before the run does is refused, naming the profile.
    #[test]
    fn refuses_a_short_profile() {
        let system = mbd_system::load_str(TEXT, "quarter-car.yaml", &Default::default()).unwrap();
        let model = system.instantiate(&system.nominal()).unwrap();
        let config = RunConfig {
            duration: 2.0,
            dt: 1e-4,
            output_every: 10,
            start: StartMode::Equilibrium,
            startup_zero_fraction: 0.0,
            startup_ramp_fraction: 0.0,
            x0: 0.0,
        };
        let short = Profile::new(vec![0.0, 1.0], vec![0.0, 0.0]).unwrap();
        let e = Excitations::new(&system, &model, &config, vec![Some(short)]).unwrap_err();
        assert!(matches!(e, crate::Error::TooShort { .. }), "{e}");
        assert!(e.to_string().contains("profile `"), "{e}");
    }
}
