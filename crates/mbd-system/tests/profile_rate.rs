//! An element whose law reads its profile's rate (a damper on a profile) stores that rate,
//! `eta_<element>_v` (m/s), right after its profile column; an undamped element on a profile
//! (the quarter car's tyre) and a contact (the vehicle-track's Hertz wheels) store none.

use mbd_system::system::{Quantity, Role};
use mbd_system::System;

fn text(file: &str) -> String {
    let path = format!("{}/../../systems/{file}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(path).unwrap()
}

fn load(text: &str) -> System {
    match mbd_system::load_str(text, "probe.yaml", &Default::default()) {
        Ok(s) => s,
        Err(d) => panic!("{d}"),
    }
}

fn rate_columns(s: &System) -> Vec<&str> {
    s.channels
        .iter()
        .filter(|c| matches!(c.quantity, Quantity::ExcitationRate(_)))
        .map(|c| c.name.as_str())
        .collect()
}

#[test]
fn a_damper_on_a_profile_stores_the_profiles_rate_after_it() {
    let s = load(&text("bridge.yaml"));
    let eta = s.channel("eta_suspension").unwrap();
    let rate = &s.channels[eta + 1];
    assert_eq!(rate.name, "eta_suspension_v");
    assert_eq!(rate.unit, "m/s");
    assert_eq!(rate.role, Role::Excitation);
    let e = s.elements.iter().position(|e| e.name == "suspension");
    assert_eq!(Some(rate.quantity), e.map(Quantity::ExcitationRate));
    assert_eq!(rate_columns(&s), ["eta_suspension_v"]);
}

#[test]
fn undamped_elements_and_contacts_store_no_rate() {
    for file in ["quarter-car.yaml", "vtcd.yaml"] {
        let s = load(&text(file));
        assert!(
            s.channels
                .iter()
                .any(|c| matches!(c.quantity, Quantity::Excitation(_))),
            "{file} stores a profile"
        );
        assert!(
            rate_columns(&s).is_empty(),
            "{file}: {:?}",
            rate_columns(&s)
        );
    }
    // The quarter car's tyre given a damping stores its road's rate.
    let tyre = "k: k_t, profile: road";
    let damped = text("quarter-car.yaml").replacen(tyre, "k: k_t, c: 100, profile: road", 1);
    assert_ne!(damped, text("quarter-car.yaml"));
    assert_eq!(rate_columns(&load(&damped)), ["eta_tyre_v"]);
}

#[test]
fn the_rate_is_not_listed_itself() {
    let bridge = text("bridge.yaml");
    let listed = bridge.replacen("eta_suspension,", "eta_suspension, eta_suspension_v,", 1);
    assert_ne!(listed, bridge);
    let report = mbd_system::load_str(&listed, "bridge.yaml", &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        report.contains("`eta_suspension_v` is a profile's rate, stored with its profile's column"),
        "{report}"
    );
}
