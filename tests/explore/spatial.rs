//! The explorer on the vehicle in space: the job of `configs/vtcd-3d.yaml` at the TINY sizes up
//! to its surrogate, served. A prediction answers every lateral channel and index with its
//! interval, and its numbers are the `predict` command's; the solver's run of the test sample
//! equals its simulated record.

use crate::api::{
    assert_equals_predict_command, check_intervals, names, series, simulated, TEST_SAMPLE,
};
use crate::Trained;
use serde_json::json;
use std::collections::BTreeMap;

/// The job's tracks at full length, runs of 1 s from 200 m: the irregularities end at 230 m,
/// so every record ends with the stability index's 0.5 s of ideal track.
const SHORT_RUN: &[&str] = &[
    "irregularity.length=240.0",
    "constants.system_values.n_f=900",
    "constants.system_values.n_m=450",
    "simulate.duration=1.0",
    "simulate.x0=200.0",
];

/// The vehicle in space's lateral quantities a user of the explorer reads.
const LATERAL_CHANNELS: [&str; 4] = ["y_w1", "psi_w1", "y_c", "phi_c"];

#[test]
fn the_vehicle_in_space_is_served_with_its_lateral_indices_and_predict_s_numbers() {
    let trained = Trained::job("configs/vtcd-3d.yaml", SHORT_RUN, &["surrogate"]);
    let served = trained.serve(&[]);
    let mut c = served.client();
    let model = c.get("/api/model").unwrap().json();
    let channels = names(&model, "channels");
    for name in LATERAL_CHANNELS {
        assert!(channels.iter().any(|c| c == name), "{name} in {channels:?}");
    }
    let indices = names(&model, "indices");
    for name in [
        pino_indices::lateral::STABILITY_INDEX,
        "derailment_quotient_2m",
        "wheelset_lateral_force_kn",
        "sperling_wy_centre",
    ] {
        assert!(indices.iter().any(|i| i == name), "{name} in {indices:?}");
    }
    let test = &model["excitation"]["test_samples"][0];
    assert_eq!(test["sample_id"], TEST_SAMPLE);
    let design: BTreeMap<String, f64> = serde_json::from_value(test["design"].clone()).unwrap();
    assert!(design.contains_key("gamma") && design.contains_key("c_yaw"));
    let excitation = json!({"kind": "test", "sample_id": TEST_SAMPLE});
    let a = c
        .post_json(
            "/api/predict",
            &json!({"design": design, "excitation": excitation}),
        )
        .unwrap();
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let pred = a.json();
    check_intervals(&model, &pred, 0.9);
    let served_indices = names(&pred, "indices");
    assert_eq!(served_indices, indices);

    // The same design and track through `predict`: the page's numbers to the bit.
    assert_equals_predict_command(&trained, &model, &design, &pred);

    // The solver's run of the test sample equals its simulated record.
    let a = c
        .post_json(
            "/api/solve",
            &json!({"design": design, "excitation": excitation}),
        )
        .unwrap();
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let solved = a.json();
    let records = simulated(&trained, &solved, &LATERAL_CHANNELS);
    for (name, expected) in LATERAL_CHANNELS.iter().zip(records) {
        assert_eq!(series(&solved, name), expected, "{name}: solve vs simulate");
    }
    assert_eq!(names(&solved, "indices"), indices);
}
