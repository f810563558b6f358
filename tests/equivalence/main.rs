//! The vehicle-track description through the generic engine reproduces, bit for bit, the
//! outputs of the hand-written engine it replaced (frozen in `golden.json`, written once from
//! that engine before it was retired): every stored column of a full sample with
//! irregularity, for both start protocols. The retired engine read the profile linearly between
//! its points; the test sets that reading in its copy of the description.
//!
//! The fixture holds each case's inputs (run controls, the sample's 14 parameters exactly,
//! the profile's seed and sample id; the profile itself comes from the live generator with
//! the description's spectrum, which drew the same points) and, per column, the BLAKE3 hash
//! of its values' bits with every 100th row for a readable message when a hash differs.

use mbd_engine::{Engine, Profile, RunConfig, StartMode};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;

const GOLDEN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/equivalence/golden.json");
/// Rows between the values kept in the fixture for the message.
const KEPT_EVERY: usize = 100;

#[derive(Debug, Serialize, Deserialize)]
struct Case {
    start: String,
    startup_zero_fraction: f64,
    startup_ramp_fraction: f64,
    duration: f64,
    dt: f64,
    output_every: usize,
    x0: f64,
    /// The sampled parameters by name.
    params: BTreeMap<String, f64>,
    /// The profile: the description's generator with these run controls.
    profile_seed: u64,
    profile_dx: f64,
    profile_length: f64,
    profile_sample: u64,
    rows: usize,
    /// Per stored column: the hash of its values and every `KEPT_EVERY`-th value.
    columns: BTreeMap<String, Column>,
}

#[derive(Debug, Serialize, Deserialize)]
struct Column {
    blake3: String,
    kept: Vec<f64>,
}

/// The shipped description with its track read `linear`, as the retired engine read it (the
/// description reads it `cubic`; everything else is the shipped file's).
fn system() -> Arc<mbd_system::System> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../systems/vtcd.yaml");
    let shipped = std::fs::read_to_string(path).unwrap();
    const READING: &str = "    interpolation: cubic\n";
    assert_eq!(
        shipped.matches(READING).count(),
        1,
        "systems/vtcd.yaml: expected its one profile read `cubic`"
    );
    let text = shipped.replace(READING, "    interpolation: linear\n");
    Arc::new(
        mbd_system::load_str(&text, "systems/vtcd.yaml", &Default::default())
            .unwrap_or_else(|d| panic!("{d}")),
    )
}

fn hash(values: &[f64]) -> String {
    let mut h = blake3::Hasher::new();
    for v in values {
        h.update(&v.to_le_bytes());
    }
    h.finalize().to_hex().to_string()
}

fn column(values: &[f64]) -> Column {
    Column {
        blake3: hash(values),
        kept: values.iter().step_by(KEPT_EVERY).copied().collect(),
    }
}

/// The generic engine's run of `case`: its time column and its stored columns by name.
fn run(case: &Case) -> (Vec<f64>, BTreeMap<String, Vec<f64>>) {
    let system = system();
    let design = system
        .sampled_by_name(case.params.iter().map(|(n, v)| (n, *v)))
        .unwrap_or_else(|e| panic!("golden.json: {e}"));
    let model = system.instantiate(&design).unwrap();
    let generators = mbd_dataset::profile_generators(
        &system,
        &mbd_dataset::profile::ProfileParams {
            seed: case.profile_seed,
            dx: case.profile_dx,
            length: case.profile_length,
        },
    )
    .unwrap();
    let generator = generators[0].as_ref().expect("a generated track profile");
    let profile = Profile::new(
        generator.positions(),
        generator.profile(case.profile_sample),
    )
    .unwrap();
    let config = RunConfig {
        duration: case.duration,
        dt: case.dt,
        output_every: case.output_every,
        start: match case.start.as_str() {
            "equilibrium" => StartMode::Equilibrium,
            "rest" => StartMode::Rest,
            other => panic!("golden.json: start `{other}`"),
        },
        startup_zero_fraction: case.startup_zero_fraction,
        startup_ramp_fraction: case.startup_ramp_fraction,
        x0: case.x0,
    };
    let engine = Engine::new(system.clone(), model, &config, vec![Some(profile)]).unwrap();
    assert!(engine.uses_fast_path(0));
    let out = engine.run().unwrap();
    let columns = system
        .channels
        .iter()
        .map(|c| c.name.clone())
        .zip(out.columns)
        .collect();
    (out.t, columns)
}

fn golden(name: &str) -> Case {
    let text = std::fs::read_to_string(GOLDEN).unwrap();
    let mut cases: BTreeMap<String, Case> = serde_json::from_str(&text).unwrap();
    cases
        .remove(name)
        .unwrap_or_else(|| panic!("golden.json: no case `{name}`"))
}

fn compare(name: &str) {
    let case = golden(name);
    let (t, columns) = run(&case);
    assert_eq!(t.len(), case.rows, "{name}: rows");
    assert_eq!(
        columns.keys().collect::<Vec<_>>(),
        case.columns.keys().collect::<Vec<_>>(),
        "{name}: the stored columns"
    );
    let mut differ = Vec::new();
    for (col, values) in &columns {
        let want = &case.columns[col];
        if hash(values) == want.blake3 {
            continue;
        }
        let got = column(values).kept;
        let row = got
            .iter()
            .zip(&want.kept)
            .position(|(a, b)| a.to_bits() != b.to_bits());
        differ.push(match row {
            Some(k) => format!(
                "{col}: row {} is {} (was {})",
                k * KEPT_EVERY,
                got[k],
                want.kept[k]
            ),
            None => format!("{col}: differs between the kept rows"),
        });
    }
    assert!(
        differ.is_empty(),
        "{name}: columns differ from the frozen engine: {differ:#?}"
    );
}

#[test]
fn vehicle_track_equals_the_retired_engine_bit_for_bit_from_equilibrium() {
    compare("equilibrium");
}

#[test]
fn vehicle_track_equals_the_retired_engine_bit_for_bit_from_rest_with_ramp() {
    compare("rest_with_ramp");
}

/// The comparison can fail: one bit changed in a parameter changes the hashes.
#[test]
fn a_one_bit_change_of_a_parameter_is_caught() {
    let mut case = golden("rest_with_ramp");
    let k_p = case.params.get_mut("k_p").unwrap();
    *k_p = f64::from_bits(k_p.to_bits() + 1);
    let (_, columns) = run(&case);
    let changed = columns
        .iter()
        .filter(|(c, v)| hash(v) != case.columns[*c].blake3)
        .count();
    assert!(changed > 0, "no column changed with k_p one ulp off");
}
