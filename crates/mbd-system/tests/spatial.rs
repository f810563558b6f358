//! Bodies in space and wheelsets on two rails in a description: the spatial DOFs, their
//! columns and inertias, 3-D points, elements and loads along an axis, a wheelset's two wheels,
//! and the refusals with the line where the problem was written (the planning checks of a
//! pipeline stop on them with exit status 2: `crates/pipeline/src/check.rs`).
//!
//! [`BASE`] is a valid spatial description (a suspended wheelset under a frame, on rails on the
//! ground); each refusal changes one thing in it and expects exactly one problem.

use mbd_system::model::{ModelEnd, PointTerms};
use mbd_system::schema::{Axis, DofKind};
use mbd_system::{load_str, System};
use std::collections::BTreeMap;

const BASE: &str = r#"format: 1
name: suspended wheelset
parameters:
  m_w: {unit: kg, nominal: 1500, range: [1400, 1600]}
  m_f: {unit: kg, value: 2500}
  v: {unit: m/s, nominal: 30, range: [20, 40]}
  k_y: {unit: N/m, value: 1.0e+6}
  k_x: {unit: N/m, value: 1.0e+7}
  e0: {unit: m, value: 0.75}
  r0: {unit: m, value: 0.43}
  b: {unit: m, value: 1.0}
  h: {unit: m, value: 0.4}
  gamma: {unit: rad, value: 0.05}
  clearance: {unit: m, value: 0.008}
  load: {unit: N, value: 1.4e+5}
bodies:
  w:
    mass: m_w
    inertia: {roll: 900, yaw: 900}
    dofs: [y, z, roll, yaw]
    points: {left: [0, -b, 0], right: [0, b, 0]}
  f:
    mass: m_f
    inertia: {roll: 1800, pitch: 2000, yaw: 2600}
    dofs: [y, z, roll, pitch, yaw]
    points: {left: [0, -b, h], right: [0, b, h], front: 1.2, rear: -1.2}
moving:
  speed: v
  points:
    rail: {on: ground, offset: 0}
elements:
  ws:
    kind: wheelset
    from: w
    rails: [rail, rail]
    half_gauge: e0
    radius: r0
    hertz: 5.18e-8
    conicity: gamma
    creep: {young: 2.06e+11, poisson: 0.3, friction: 0.4, rail_radius: 0.3}
    flange: {clearance: clearance, stiffness: 1.0e+7}
  x_l: {kind: spring_damper, direction: x, from: f.left, to: w.left, k: k_x}
  x_r: {kind: spring_damper, direction: x, from: f.right, to: w.right, k: k_x}
  y_l: {kind: spring_damper, direction: y, from: f.left, to: w.left, k: k_y}
  y_r: {kind: spring_damper, direction: y, from: f.right, to: w.right, k: k_y}
  z_l: {kind: spring_damper, from: f.left, to: w.left, k: k_x}
  z_r: {kind: spring_damper, from: f.right, to: w.right, k: k_x}
  z_f: {kind: spring_damper, from: f.front, to: ground, k: k_y}
  z_b: {kind: spring_damper, from: f.rear, to: ground, k: k_y}
  yaw_f: {kind: spring_damper, direction: x, from: f.left, to: ground, k: k_y}
  lat_f: {kind: table, direction: y, from: f, to: ground, deflection: [-0.02, 0, 0.02], force: [-2.0e+4, 0, 2.0e+4]}
loads:
  weight: {at: w, force: load}
  side: {at: f.left, force: 100, direction: y}
outputs: [p_ws_l, p_ws_r, fy_ws_l, fy_ws_r, ff_ws_r, dy_ws_r, f_y_l]
"#;

fn edit(text: &str, from: &str, to: &str) -> String {
    assert_eq!(text.matches(from).count(), 1, "`{from}` is not unique");
    text.replacen(from, to, 1)
}

fn line_of(text: &str, needle: &str) -> usize {
    let lines: Vec<usize> = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.contains(needle))
        .map(|(i, _)| i + 1)
        .collect();
    assert_eq!(lines.len(), 1, "`{needle}` is on lines {lines:?}");
    lines[0]
}

fn load(text: &str) -> System {
    load_str(text, "probe.yaml", &BTreeMap::new()).unwrap_or_else(|d| panic!("{d}"))
}

/// The one problem of a description that must be refused, checked to sit at the line holding
/// `at` and to contain every one of `says`.
fn refused(text: &str, at: &str, says: &[&str]) {
    let report = match load_str(text, "probe.yaml", &BTreeMap::new()) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(d) => d.to_string(),
    };
    let lines: Vec<&str> = report.lines().collect();
    assert_eq!(lines.len(), 1, "one problem expected:\n{report}");
    let prefix = format!("probe.yaml:{}:", line_of(text, at));
    assert!(
        lines[0].starts_with(&prefix),
        "{report}\nexpected at {prefix}"
    );
    for s in says {
        assert!(lines[0].contains(s), "{report}\nexpected `{s}`");
    }
}

#[test]
fn base_compiles_with_spatial_columns_and_inertias() {
    let s = load(BASE);
    let names: Vec<&str> = s.dofs.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(
        names,
        ["y_w", "z_w", "phi_w", "psi_w", "y_f", "z_f", "phi_f", "beta_f", "psi_f"]
    );
    // The wheelset became one contact per wheel, with its columns.
    let wheels: Vec<&str> = s.elements.iter().take(2).map(|e| e.name.as_str()).collect();
    assert_eq!(wheels, ["ws_l", "ws_r"]);
    for c in [
        "p_ws_l", "fy_ws_r", "ff_ws_r", "dy_ws_r", "phi_w_a", "psi_f_v",
    ] {
        assert!(s.channel(c).is_some(), "no column {c}");
    }
    let model = s.instantiate(&s.nominal()).unwrap();
    // Masses of the translations, inertias of the rotations.
    assert_eq!(
        model.dof_mass,
        [
            1500.0,
            1500.0,
            900.0,
            900.0,
            2500.0,
            2500.0,
            1800.0,
            2000.0,
            2500.0 + 100.0
        ]
    );
    // The wheels' vertical contacts sit at y = -/+ e0 and roll the wheelset by that arm.
    let ModelEnd::Body(left) = model.elements[0].from else {
        panic!("a body end")
    };
    assert_eq!(
        left,
        PointTerms {
            z: Some(1),
            pitch: None,
            roll: Some((2, -0.75))
        }
    );
    // The wheelset's DOFs have no equation for a learner (its wheels' creep is not a
    // coefficient group); the frame's do.
    let eq = s.equation_dofs(&[], &[]);
    assert_eq!(eq, [4, 5, 6, 7, 8]);
}

/// A lateral spring above a body's centre rolls it, a longitudinal one beside it yaws it, a
/// vertical one beside it rolls it: the assembly's coefficient of each DOF is the lever arm
/// of `theta x r`, checked against the cross product written out here.
#[test]
fn assembly_follows_the_small_rotation_cross_product() {
    let s = load(BASE);
    let model = s.instantiate(&s.nominal()).unwrap();
    let n = s.dofs.len();
    // Element `y_l`: from f.left = (0, -1, 0.4) along y; to w.left = (0, -1, 0).
    let cross = |r: [f64; 3], e: [f64; 3]| {
        [
            r[1] * e[2] - r[2] * e[1],
            r[2] * e[0] - r[0] * e[2],
            r[0] * e[1] - r[1] * e[0],
        ]
    };
    for (name, axis) in [("y_l", Axis::Y), ("x_r", Axis::X), ("z_l", Axis::Z)] {
        let e = s.elements.iter().position(|el| el.name == name).unwrap();
        assert_eq!(s.elements[e].direction, axis);
        let unit = match axis {
            Axis::X => [1.0, 0.0, 0.0],
            Axis::Y => [0.0, 1.0, 0.0],
            Axis::Z => [0.0, 0.0, 1.0],
        };
        let side = if name.ends_with("_l") { -1.0 } else { 1.0 };
        // d(u . e)/d(theta) = r x e for the frame's point and the wheelset's point.
        let frame = cross([0.0, side, 0.4], unit);
        let wheel = cross([0.0, side, 0.0], unit);
        let b = model.elements[e].incidence(n);
        let k = |kind| {
            s.dofs
                .iter()
                .position(|d| d.kind == kind && d.body == 1)
                .unwrap()
        };
        let kw = |kind| {
            s.dofs
                .iter()
                .position(|d| d.kind == kind && d.body == 0)
                .unwrap()
        };
        assert_eq!(b[k(DofKind::Roll)], frame[0], "{name} roll of f");
        assert_eq!(b[k(DofKind::Pitch)], frame[1], "{name} pitch of f");
        assert_eq!(b[k(DofKind::Yaw)], frame[2], "{name} yaw of f");
        assert_eq!(b[kw(DofKind::Roll)], -wheel[0], "{name} roll of w");
        assert_eq!(b[kw(DofKind::Yaw)], -wheel[2], "{name} yaw of w");
    }
}

#[test]
fn a_spatial_element_on_a_planar_body_is_refused() {
    let text = edit(
        BASE,
        "    dofs: [y, z, roll, pitch, yaw]\n",
        "    dofs: [z, pitch]\n",
    );
    let text = edit(
        &text,
        "    inertia: {roll: 1800, pitch: 2000, yaw: 2600}",
        "    inertia: 2000",
    );
    let report = match load_str(&text, "probe.yaml", &BTreeMap::new()) {
        Ok(_) => panic!("accepted"),
        Err(d) => d.to_string(),
    };
    // Every lateral element of the frame and the lateral load, at its line (a longitudinal
    // spring below the frame's centre still pitches it: accepted).
    assert_eq!(report.lines().count(), 4, "{report}");
    for (needle, what) in [
        (
            "  y_l:",
            "elements.y_l.direction: `y` acts on a planar body",
        ),
        (
            "  y_r:",
            "elements.y_r.direction: `y` acts on a planar body",
        ),
        (
            "  lat_f:",
            "elements.lat_f.direction: `y` acts on a planar body",
        ),
        ("  side:", "loads.side.direction: `y` acts on a planar body"),
    ] {
        let line = line_of(&text, needle);
        assert!(
            report
                .lines()
                .any(|l| l.starts_with(&format!("probe.yaml:{line}:")) && l.contains(what)),
            "{report}\nexpected `{what}` at line {line}"
        );
    }
    assert!(
        report.contains("body `f` has the DOFs [z, pitch]"),
        "{report}"
    );
}

#[test]
fn a_negative_flange_clearance_is_refused() {
    let text = edit(
        BASE,
        "clearance: {unit: m, value: 0.008}",
        "clearance: {unit: m, value: -0.001}",
    );
    refused(
        &text,
        "flange: {clearance: clearance",
        &[
            "`elements.ws.flange.clearance` = -0.001 is out of range",
            ">= 0",
        ],
    );
}

#[test]
fn a_conicity_outside_its_range_is_refused() {
    for bad in ["0.7", "0", "-0.05"] {
        let text = edit(
            BASE,
            "gamma: {unit: rad, value: 0.05}",
            &format!("gamma: {{unit: rad, value: {bad}}}"),
        );
        refused(
            &text,
            "conicity: gamma",
            &["`elements.ws.conicity`", "in (0, 0.6]"],
        );
    }
    let text = edit(
        BASE,
        "gamma: {unit: rad, value: 0.05}",
        "gamma: {unit: rad, value: 0.6}",
    );
    load(&text);
}

#[test]
fn a_dof_declared_twice_is_refused() {
    let text = edit(
        BASE,
        "    dofs: [y, z, roll, yaw]\n",
        "    dofs: [y, z, roll, yaw, y]\n",
    );
    refused(
        &text,
        "dofs: [y, z, roll, yaw, y]",
        &["bodies.w.dofs: `y` listed twice"],
    );
}

#[test]
fn a_rotation_without_its_inertia_is_refused() {
    let text = edit(
        BASE,
        "    inertia: {roll: 900, yaw: 900}\n",
        "    inertia: {yaw: 900}\n",
    );
    refused(
        &text,
        "inertia: {yaw: 900}",
        &["a body with a roll DOF needs `inertia: {roll: ...}`"],
    );
    let text = edit(
        BASE,
        "    inertia: {roll: 900, yaw: 900}\n",
        "    inertia: {roll: 900, pitch: 3, yaw: 900}\n",
    );
    refused(
        &text,
        "pitch: 3",
        &["bodies.w.inertia.pitch: the body has no pitch DOF"],
    );
}

#[test]
fn a_wheelset_on_a_planar_body_is_refused() {
    let text = edit(BASE, "    dofs: [y, z, roll, yaw]\n", "    dofs: [y, z]\n");
    let text = edit(&text, "    inertia: {roll: 900, yaw: 900}\n", "");
    let report = load_str(&text, "probe.yaml", &BTreeMap::new())
        .unwrap_err()
        .to_string();
    let line = line_of(&text, "    from: w");
    assert!(
        report
            .lines()
            .any(|l| l.starts_with(&format!("probe.yaml:{line}:"))
                && l.contains("needs the DOFs y, z, roll and yaw")
                && l.contains("lacks roll, yaw")),
        "{report}"
    );
}

#[test]
fn a_wheelset_names_two_rails_and_a_geometry() {
    let text = edit(BASE, "rails: [rail, rail]", "rails: [rail]");
    refused(&text, "rails: [rail]", &["[left, right]: 2 names, found 1"]);
    let text = edit(BASE, "    conicity: gamma\n", "");
    let text = edit(&text, "  gamma: {unit: rad, value: 0.05}\n", "");
    refused(&text, "  ws:", &["give the contact geometry"]);
    let tabulated = |shifts: &str| {
        let text = edit(
            BASE,
            "    conicity: gamma\n",
            &format!("    geometry: {{shift: [{shifts}], radius: [-5.0e-4, 0, 5.0e-4], angle: [0.01, 0.03, 0.05]}}\n"),
        );
        edit(&text, "  gamma: {unit: rad, value: 0.05}\n", "")
    };
    let s = load(&tabulated("-0.01, 0, 0.01"));
    assert!(s.instantiate(&s.nominal()).is_ok());
    refused(
        &tabulated("-0.01, 0.02, 0.01"),
        "geometry: {shift",
        &["`elements.ws.geometry.shift[2]`"],
    );
}

/// A profile combining others: its terms resolve, a combination of combinations is refused.
#[test]
fn profile_combinations() {
    let with = |profiles: &str| {
        edit(
            BASE,
            "elements:\n",
            &format!("profiles:\n{profiles}elements:\n"),
        )
    };
    let text = with("  v: {kind: harmonic, amplitude: 1.0e-3, wavelength: 20}\n  c: {kind: harmonic, amplitude: 2.0e-3, wavelength: 30}\n  left: {kind: combination, of: {v: 1, c: -0.5}}\n");
    let text = edit(
        &text,
        "    rails: [rail, rail]\n",
        "    rails: [rail, rail]\n    profiles: [left, v]\n",
    );
    let text = edit(&text, "outputs: [", "outputs: [eta_ws_l, ");
    let s = load(&text);
    let model = s.instantiate(&s.nominal()).unwrap();
    assert_eq!(
        model.profiles[2],
        mbd_system::model::ModelProfile::Combination(vec![(0, 1.0), (1, -0.5)])
    );
    assert!(s.channel("eta_ws_l").is_some());
    let text = with("  v: {kind: harmonic, amplitude: 1.0e-3, wavelength: 20}\n  a: {kind: combination, of: {v: 1}}\n  b: {kind: combination, of: {a: 1}}\n");
    refused(
        &text,
        "b: {kind: combination",
        &["`a` is itself a combination"],
    );
}

/// The lateral binding a valid [`BASE`] takes (the frame stands in for a car body).
const LATERAL: &str = "lateral:
  wheelsets: [ws]
  car_body: {lateral: y_f_a, yaw: psi_f_a, roll: phi_f_a}
  half_length: 1.2
  floor: h
  axle_load: load
  stability: y_w
  limits: {derailment_quotient: 0.8, lateral_force: 1.0, sperling: 2.5}
";

/// The lateral binding resolves its wheelset's wheels to their `Y` and `Q` columns, left before
/// right, its constants to expressions and its limits to literals; a name that is not a
/// wheelset and a wheel column that is not stored are refused at their lines.
#[test]
fn the_lateral_binding_names_wheelsets_and_stored_columns() {
    let text = format!("{BASE}{LATERAL}");
    let s = load(&text);
    let l = s.lateral.as_ref().expect("a lateral binding");
    let col = |c: usize| s.channels[c].name.as_str();
    let wheels: Vec<[&str; 2]> = l.wheels.iter().map(|w| w.map(col)).collect();
    assert_eq!(wheels, [["fy_ws_l", "p_ws_l"], ["fy_ws_r", "p_ws_r"]]);
    assert_eq!(l.car_body.map(col), ["y_f_a", "psi_f_a", "phi_f_a"]);
    assert_eq!(col(l.stability), "y_w");
    let values = s.values(&s.nominal()).unwrap();
    assert_eq!(l.floor.eval(&values), 0.4);
    assert_eq!(l.axle_load.eval(&values), 1.4e5);
    assert_eq!(l.prudhomme.eval(&values), 1.0);
    assert_eq!(l.limits.derailment_quotient, Some(0.8));
    assert_eq!(l.limits.stability, None);
    refused(
        &edit(&text, "wheelsets: [ws]", "wheelsets: [x_l]"),
        "wheelsets: [x_l]",
        &["`x_l` is not a wheelset", "wheelsets: ws"],
    );
    refused(
        &edit(&text, "fy_ws_l, ", ""),
        "wheelsets: [ws]",
        &["`fy_ws_l` is not a stored column"],
    );
}

/// A generated profile that ends: `until` compiles to its end and taper; a taper longer than
/// the distance to the end is refused at its line.
#[test]
fn a_profile_ends_where_until_says() {
    let text = edit(
        BASE,
        "elements:\n",
        "profiles:
  track:
    kind: generated
    psd: {iso8608: C}
    wavelengths: [1, 50]
    until: {x: 120, taper: 10}
elements:\n",
    );
    let text = edit(
        &text,
        "    rails: [rail, rail]\n",
        "    rails: [rail, rail]\n    profiles: [track, track]\n",
    );
    let s = load(&text);
    let model = s.instantiate(&s.nominal()).unwrap();
    assert_eq!(model.profile_ends, [Some([120.0, 10.0])]);
    refused(
        &edit(&text, "taper: 10}", "taper: 130}"),
        "taper: 130}",
        &["until.taper", "at most until.x = 120 m"],
    );
}

/// The shipped spatial vehicle compiles with both index families bound: four wheelsets' eight
/// wheels, the car body's three accelerations, the leading wheelset's lateral shift.
#[test]
fn the_shipped_spatial_vehicle_binds_both_families() {
    let path = format!("{}/../../systems/vtcd-3d.yaml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap();
    let s =
        load_str(&text, "systems/vtcd-3d.yaml", &BTreeMap::new()).unwrap_or_else(|d| panic!("{d}"));
    let l = s.lateral.as_ref().expect("a lateral binding");
    assert_eq!(l.wheels.len(), 8);
    assert_eq!(s.channels[l.stability].name, "y_w1");
    assert!(s.railway.is_some());
    let model = s.instantiate(&s.nominal()).unwrap();
    assert!(model
        .profile_ends
        .iter()
        .flatten()
        .all(|e| *e == [230.0, 10.0]));
    assert_eq!(model.profile_ends.iter().flatten().count(), 3);
}
