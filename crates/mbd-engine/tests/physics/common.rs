//! Shared helpers: loading descriptions and variants of them, building engines, reading columns,
//! the per-column error measure of `systems-interfaces.md`.

use mbd_engine::{Engine, Profile, Route, RunConfig, StartMode, Trajectory};
use mbd_system::System;
use std::collections::BTreeMap;
use std::sync::Arc;

/// The text of `systems/<name>`.
pub fn system_text(name: &str) -> String {
    let path = format!("{}/../../systems/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// `text` with `from` replaced by `to`, which must occur exactly once (a variant that silently
/// stopped applying would test the wrong system).
pub fn replace_once(text: &str, from: &str, to: &str) -> String {
    let n = text.matches(from).count();
    assert_eq!(n, 1, "`{from}` occurs {n} times in the description");
    text.replacen(from, to, 1)
}

/// A description compiled with fixed-value overrides (`name = value`).
pub fn load(text: &str, overrides: &[(&str, f64)]) -> Arc<System> {
    let o: BTreeMap<String, mbd_system::Override> = overrides
        .iter()
        .map(|(k, v)| (k.to_string(), mbd_system::Override::Value(*v)))
        .collect();
    Arc::new(mbd_system::load_str(text, "variant.yaml", &o).unwrap_or_else(|d| panic!("{d}")))
}

/// Run controls with the profiles on from `t = 0`.
pub fn config(duration: f64, dt: f64, every: usize, start: StartMode, x0: f64) -> RunConfig {
    RunConfig {
        duration,
        dt,
        output_every: every,
        start,
        startup_zero_fraction: 0.0,
        startup_ramp_fraction: 0.0,
        x0,
    }
}

/// The engine of one design.
pub fn engine(
    system: &Arc<System>,
    sampled: &mbd_system::Sampled,
    config: &RunConfig,
    profiles: Vec<Option<Profile>>,
    route: Route,
) -> Engine {
    let model = system.instantiate(sampled).unwrap();
    Engine::with_route(system.clone(), model, config, profiles, route)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// The stored column `name`.
pub fn column<'a>(system: &System, traj: &'a Trajectory, name: &str) -> &'a [f64] {
    let i = system
        .channel(name)
        .unwrap_or_else(|| panic!("no column {name}"));
    &traj.columns[i]
}

/// `max |a - b| / max |b|` (the per-column measure of `systems-interfaces.md`).
pub fn relative_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let diff = a
        .iter()
        .zip(b)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let scale = b.iter().map(|b| b.abs()).fold(0.0, f64::max);
    diff / scale
}

/// `max |x|`.
pub fn peak(x: &[f64]) -> f64 {
    x.iter().map(|x| x.abs()).fold(0.0, f64::max)
}

/// Start of the moving frame on the short track (m): the rear wheel at 3 m, the front one at
/// 23.4 m (nominal lengths), 33 m after 0.1 s at the top speed.
pub const SHORT_X0: f64 = 3.0;

/// `systems/vtcd.yaml` on a 36 m track: 60 supports and 30 modes (the modal wavenumbers per
/// metre of the full 540 m track with 450 modes), with further fixed-value overrides.
pub fn short_track(text: &str, overrides: &[(&str, f64)]) -> Arc<System> {
    let mut all = vec![("n_f", 60.0), ("n_m", 30.0)];
    all.extend_from_slice(overrides);
    load(text, &all)
}

/// The first generated profile of `system` from the live generator (`mbd_dataset`, as the
/// `irregularity` stage draws it): `seed`, spacing `dx` and `length` (m), sample `id`.
pub fn generated_profile(system: &System, seed: u64, dx: f64, length: f64, id: u64) -> Profile {
    let generator = first_generator(system, seed, dx, length);
    Profile::new(generator.positions(), generator.profile(id)).unwrap()
}

/// The live generator of the first generated profile of `system`.
pub fn first_generator(
    system: &System,
    seed: u64,
    dx: f64,
    length: f64,
) -> mbd_dataset::ProfileGenerator {
    let params = mbd_dataset::ProfileParams { seed, dx, length };
    mbd_dataset::profile_generators(system, &params)
        .unwrap()
        .into_iter()
        .flatten()
        .next()
        .expect("a generated profile")
}

/// The vehicle-track description's TB/T 3352 track over 120 m (seed 11, 0.1 m spacing),
/// sample `id`.
pub fn track_profile(id: u64) -> Profile {
    generated_profile(&load(&system_text("vtcd.yaml"), &[]), 11, 0.1, 120.0, id)
}

/// The value of parameter `name` in a sample's model.
pub fn value(system: &System, model: &mbd_system::model::Model, name: &str) -> f64 {
    model.values[system
        .parameter(name)
        .unwrap_or_else(|| panic!("no parameter {name}"))]
}

/// `text` with parameter `name` (one line `  name: {unit: U, ...}`) made the fixed value
/// `value` (keeping its unit): a sampled parameter cannot be overridden outside its range.
pub fn fix_parameter(text: &str, name: &str, value: f64) -> String {
    let key = format!("\n  {name}: {{unit: ");
    let start = text
        .find(&key)
        .unwrap_or_else(|| panic!("no parameter line for {name}"))
        + 1;
    assert_eq!(text.matches(&key).count(), 1, "{name} declared once");
    let end = start + text[start..].find('\n').expect("line end");
    let line = &text[start..end];
    let unit = line[key.len() - 1..].split(',').next().expect("a unit");
    format!(
        "{}  {name}: {{unit: {unit}, value: {value:e}}}{}",
        &text[..start],
        &text[end..]
    )
}

/// The vehicle-track description at standstill (`v_kmh` = 0).
pub fn standstill(text: &str) -> String {
    fix_parameter(text, "v_kmh", 0.0)
}
