//! The excitations of a run without running it: the profile under every element that reads
//! one, `eta_e(t) = r(t) profile(x0 + v t + o_e)` (m, positive downward: a dip), with `v` the
//! frame speed, `o_e` the offset of the moving point the element rests on and `r` the start-up
//! factor of the run controls ([`RunConfig::ramp`]). These are the values the engine's force
//! evaluation reads at the same `t`, so a learned operator (`predict`) sees the inputs the
//! solver saw.

use crate::coverage::check_coverage;
use crate::engine::profile_sources;
use crate::{Profile, ProfileSource, Result, RunConfig};
use mbd_system::model::{Model, ModelEnd};
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Engine, StartMode};
    use mbd_system::system::Interpolation;
    use std::sync::Arc;

    const TEXT: &str = include_str!("../../../systems/quarter-car.yaml");

    /// The excitation columns of a run equal what `Excitations` computes at the stored times,
    /// bit for bit, through the start-up ramp and after it, with the road read linearly (the
    /// shipped quarter car) and by a cubic spline.
    #[test]
    fn equals_the_engines_stored_excitation() {
        let band = "    wavelengths: [0.5, 90.0]";
        assert_eq!(TEXT.matches(band).count(), 1);
        let cubic = TEXT.replace(band, &format!("    interpolation: cubic\n{band}"));
        for (text, interpolation) in [
            (TEXT, Interpolation::Linear),
            (cubic.as_str(), Interpolation::Cubic),
        ] {
            equals_the_engines_stored_excitation_of(text, interpolation);
        }
    }

    fn equals_the_engines_stored_excitation_of(text: &str, interpolation: Interpolation) {
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
        let mut checked = 0;
        for (c, ch) in system.channels.iter().enumerate() {
            if let mbd_system::system::Quantity::Excitation(e) = ch.quantity {
                assert!(ex.reads_profile(e));
                for (k, &t) in run.t.iter().enumerate() {
                    assert_eq!(ex.at(e, t), run.columns[c][k], "{} at t = {t}", ch.name);
                }
                assert!(run.columns[c].iter().any(|v| *v != 0.0) && run.columns[c][0] == 0.0);
                checked += 1;
            }
        }
        assert!(checked > 0, "the quarter car stores its road input");
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
