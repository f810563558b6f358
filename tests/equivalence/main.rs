//! The vehicle-track description through the generic engine equals the hand-written engine it
//! replaces (`vtcd`, kept only as this reference), bit for bit: every stored column of a full
//! sample with irregularity, for both start protocols.

use mbd_engine::{Engine, Profile, RunConfig, StartMode};
use std::sync::Arc;
use vtcd::params::SampleParams;
use vtcd::simulation::{Simulation, SimulationConfig};

fn system() -> Arc<mbd_system::System> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../systems/vtcd.yaml");
    let text = std::fs::read_to_string(path).unwrap();
    Arc::new(
        mbd_system::load_str(&text, "systems/vtcd.yaml", &Default::default())
            .unwrap_or_else(|d| panic!("{d}")),
    )
}

fn compare(start: StartMode, zero: f64, ramp: f64, duration: f64, sample: u64) {
    let plan = vtcd::sampling::SamplingParams {
        seed: 1,
        n_train: 10,
        n_validation: 1,
        n_test: 1,
        ranges: Default::default(),
    }
    .validate()
    .unwrap();
    let params: SampleParams = plan.draw(sample);
    let generator = vtcd::irregularity::IrregularityParams::with_seed(1)
        .validate()
        .unwrap();
    let eta = generator.profile(sample);
    let x = generator.positions();
    let reference_config = SimulationConfig {
        duration,
        start: match start {
            StartMode::Equilibrium => vtcd::simulation::StartMode::Equilibrium,
            StartMode::Rest => vtcd::simulation::StartMode::Rest,
        },
        startup_zero_fraction: zero,
        startup_ramp_fraction: ramp,
        ..Default::default()
    };
    let reference = Simulation::new(
        &params,
        &reference_config,
        Some(vtcd::simulation::Profile::new(x.clone(), eta.clone()).unwrap()),
    )
    .unwrap()
    .run()
    .unwrap();

    let system = system();
    let model = system.instantiate(&params.to_array()).unwrap();
    let config = RunConfig {
        duration,
        dt: 1e-4,
        output_every: 10,
        start,
        startup_zero_fraction: zero,
        startup_ramp_fraction: ramp,
        x0: 20.0,
    };
    let engine = Engine::new(
        system.clone(),
        model,
        &config,
        vec![Some(Profile::new(x, eta).unwrap())],
    )
    .unwrap();
    assert!(engine.uses_fast_path(0));
    let out = engine.run().unwrap();
    assert_eq!(out.t, reference.t);
    assert_eq!(out.columns.len(), reference.columns.len());
    for (i, (a, b)) in out.columns.iter().zip(&reference.columns).enumerate() {
        let name = &system.channels[i].name;
        let first = a
            .iter()
            .zip(b)
            .position(|(x, y)| x.to_bits() != y.to_bits());
        if let Some(row) = first {
            let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let err = a
                .iter()
                .zip(b)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
                / scale;
            panic!(
                "column {name}: first difference at row {row}: {} vs {} (max relative {err:e})",
                a[row], b[row]
            );
        }
    }
}

#[test]
fn vehicle_track_equals_the_reference_engine_bit_for_bit_from_equilibrium() {
    compare(StartMode::Equilibrium, 0.0, 0.0, 2.0, 3);
}

#[test]
fn vehicle_track_equals_the_reference_engine_bit_for_bit_from_rest_with_ramp() {
    compare(StartMode::Rest, 0.1, 0.1, 1.0, 7);
}
