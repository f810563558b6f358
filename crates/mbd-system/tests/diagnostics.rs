//! Bad descriptions get a clear error: every problem is reported as `file:line:col: message`
//! at the line where it was written, naming the offending name and what was expected, and all
//! problems of one check stage come in one report, sorted by line.
//!
//! Each test starts from [`BASE`], a small valid description (one pitching body on a modal beam
//! and the ground, a harmonic profile, a sensor, a load), changes one thing and checks the
//! report. `BASE` itself must compile (first test), so every failure below is caused by the
//! change alone; most tests also assert that the change gives exactly one problem, so a
//! follow-on message (a parameter "never used" because the expression naming it failed) would
//! be caught.
//!
//! The stages, each reporting every problem it finds: YAML syntax (the first error), the shape
//! of each section and field, names and expressions, then (only when all of those pass) the
//! values at the nominal parameters and the restraint of every DOF.

use mbd_system::{load_str, System};
use std::collections::BTreeMap;

const BASE: &str = r#"format: 1
name: probe
parameters:
  m: {unit: kg, nominal: 2, range: [1, 3]}
  j: {unit: kg m^2, value: 0.5}
  k: {unit: N/m, value: 8.0e+5}
  a: {unit: m, value: 1.5}
  n: {unit: "1", value: 4}
  v: {unit: m/s, nominal: 10, range: [5, 20]}
bodies:
  c:
    mass: m
    inertia: j
    dofs: [z, pitch]
    points: {front: a, rear: -a}
beams:
  r:
    length: 40
    modes: n
    mass_per_length: 60
    bending_stiffness: 1.0e+6
moving:
  speed: v
  points:
    p1: {on: r, offset: 2 * a}
    g1: {on: ground, offset: 0}
sensors:
  mid: {on: r, x: 20}
profiles:
  bumps: {kind: harmonic, amplitude: 1.0e-3, wavelength: 2}
elements:
  front: {kind: spring_damper, from: c.front, to: p1, k: k, profile: bumps}
  rear: {kind: spring_damper, from: c.rear, to: g1, k: k}
loads:
  weight: {at: c, force: m * 9.81}
outputs: [z_p1, z_mid, eta_front, f_front]
"#;

/// `BASE` with `from` (which must occur exactly once) replaced by `to`.
fn edit(text: &str, from: &str, to: &str) -> String {
    assert_eq!(text.matches(from).count(), 1, "`{from}` is not unique");
    text.replacen(from, to, 1)
}

/// The 1-based line of the only line of `text` containing `needle`.
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

/// The report of a description that must be refused.
fn report(text: &str) -> String {
    match load_str(text, "bad.yaml", &BTreeMap::new()) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(d) => d.to_string(),
    }
}

/// Asserts that `report` has a problem at the line of `needle` in `text` whose message holds
/// every one of `parts`; returns that problem's line of the report.
fn expect(report: &str, text: &str, needle: &str, parts: &[&str]) -> String {
    let prefix = format!("bad.yaml:{}:", line_of(text, needle));
    report
        .lines()
        .find(|l| l.starts_with(&prefix) && parts.iter().all(|p| l.contains(p)))
        .unwrap_or_else(|| panic!("no problem `{prefix}` with {parts:?} in\n{report}"))
        .to_owned()
}

/// Asserts that `text` is refused with exactly one problem, at the line of `needle`, holding
/// every one of `parts`.
fn only(text: &str, needle: &str, parts: &[&str]) {
    let report = report(text);
    expect(&report, text, needle, parts);
    assert_eq!(
        report.lines().count(),
        1,
        "more than one problem:\n{report}"
    );
}

fn compiles(text: &str) -> System {
    load_str(text, "base.yaml", &BTreeMap::new()).unwrap_or_else(|d| panic!("{d}"))
}

#[test]
fn the_base_description_compiles_with_its_columns() {
    let s = compiles(BASE);
    let cols: Vec<&str> = s.channels.iter().map(|c| c.name.as_str()).collect();
    // DOF displacements, listed displacement columns, DOF velocities, DOF accelerations, the
    // other listed columns.
    assert_eq!(
        cols,
        [
            "z_c",
            "beta_c",
            "z_p1",
            "z_mid",
            "z_c_v",
            "beta_c_v",
            "z_c_a",
            "beta_c_a",
            "eta_front",
            "f_front"
        ]
    );
    assert_eq!(s.sampled_names(), ["m", "v"]);
    s.instantiate(&s.nominal()).unwrap();
}

#[test]
fn unknown_body_names_the_bodies_and_points_expected() {
    let text = edit(BASE, "from: c.front", "from: car.front");
    only(
        &text,
        "front: {kind",
        &[
            "elements.front.from",
            "unknown point `car.front`",
            "`ground`, a body (c), `body.point`, or a moving point (p1, g1)",
        ],
    );
    let text = edit(BASE, "at: c,", "at: cab,");
    only(
        &text,
        "weight:",
        &["loads.weight.at", "unknown point `cab`"],
    );
}

#[test]
fn unknown_point_of_a_body_names_its_points() {
    let text = edit(BASE, "from: c.rear", "from: c.nope");
    only(
        &text,
        "rear: {kind",
        &[
            "elements.rear.from",
            "body `c` has no point `nope`",
            "its points: front, rear",
        ],
    );
}

#[test]
fn unknown_parameter_in_an_expression_lists_the_parameters() {
    let text = edit(BASE, "mass: m", "mass: m * q");
    // `m` is still used: no follow-on "never used" for it.
    only(
        &text,
        "mass: m * q",
        &[
            "bodies.c.mass",
            "unknown parameter `q`",
            "parameters: a, j, k, m, n, v",
        ],
    );
    // In a derived parameter.
    let text = edit(
        BASE,
        "  v: {unit",
        "  w: {unit: N, expr: m * gravity}\n  v: {unit",
    );
    let text = edit(&text, "force: m * 9.81", "force: w");
    only(
        &text,
        "w: {unit",
        &[
            "parameters.w.expr",
            "unknown parameter `gravity`",
            "parameters: a, j, k, m, n, v, w",
        ],
    );
}

#[test]
fn unknown_beam_and_profile_list_the_known_ones() {
    let text = edit(BASE, "p1: {on: r,", "p1: {on: rail,");
    only(
        &text,
        "p1: {on",
        &[
            "moving.points.p1.on",
            "unknown beam `rail`",
            "beams: r; or `ground`",
        ],
    );
    let text = edit(BASE, "mid: {on: r,", "mid: {on: deck,");
    only(
        &text,
        "mid: {on",
        &["sensors.mid.on", "unknown beam `deck`", "beams: r"],
    );
    let text = edit(BASE, "profile: bumps", "profile: bump");
    only(
        &text,
        "front: {kind",
        &[
            "elements.front.profile",
            "unknown profile `bump`",
            "profiles: bumps",
        ],
    );
}

#[test]
fn a_parameter_declared_twice_names_both_lines() {
    let text = edit(BASE, "  v: {unit", "  k: {unit: N/m, value: 9}\n  v: {unit");
    only(
        &text,
        "k: {unit: N/m, value: 9}",
        &[
            "duplicate key `k`",
            &format!("first written at line {}", line_of(BASE, "k: {unit")),
        ],
    );
}

#[test]
fn a_parameter_never_used_is_named() {
    let text = edit(
        BASE,
        "  v: {unit",
        "  spare: {unit: N/m, value: 9}\n  v: {unit",
    );
    only(
        &text,
        "spare:",
        &["parameters.spare", "declared but never used"],
    );
}

#[test]
fn a_cycle_of_derived_parameters_is_named() {
    let text = edit(
        BASE,
        "  a: {unit: m, value: 1.5}",
        "  a: {unit: m, expr: 2 * b}\n  b: {unit: m, expr: a / 2 + 1}",
    );
    only(
        &text,
        "a: {unit",
        &["derived parameters form a cycle: a -> b -> a"],
    );
    let text = edit(
        BASE,
        "  a: {unit: m, value: 1.5}",
        "  a: {unit: m, expr: a + 1}",
    );
    only(&text, "a: {unit", &["cycle: a -> a"]);
}

#[test]
fn a_non_numeric_or_unparsable_expression_says_what_was_expected() {
    let text = edit(BASE, "mass: m", "mass: \"m $ 2\"");
    only(
        &text,
        "mass:",
        &[
            "bodies.c.mass",
            "not an expression",
            "column 3 of `m $ 2`",
            "unexpected `$`",
        ],
    );
    let text = edit(BASE, "mass: m", "mass: [m]");
    only(
        &text,
        "mass:",
        &[
            "bodies.c.mass",
            "expected a number or an expression, found a list",
        ],
    );
    let text = edit(BASE, "mass: m", "mass: gamma(m)");
    only(
        &text,
        "mass:",
        &["unknown function `gamma`", "functions: sqrt"],
    );
    let text = edit(BASE, "mass: m", "mass: 2 * (m");
    only(&text, "mass:", &["bodies.c.mass", "expected `)`"]);
    // A literal that is not finite.
    let text = edit(BASE, "mass_per_length: 60", "mass_per_length: .nan");
    only(
        &text,
        "mass_per_length",
        &["beams.r.mass_per_length", "not a finite number"],
    );
    // A parameter's own value is a number, not an expression; and its expression must parse
    // (one problem each, no follow-on about the parameter's kind).
    let text = edit(BASE, "value: 1.5", "value: one");
    only(
        &text,
        "a: {unit",
        &[
            "parameters.a.value",
            "expected a finite number, found `one`",
        ],
    );
    let text = edit(
        BASE,
        "  a: {unit: m, value: 1.5}",
        "  a: {unit: m, expr: \"1 +\"}",
    );
    only(
        &text,
        "a: {unit",
        &["parameters.a.expr", "not an expression"],
    );
}

#[test]
fn non_positive_masses_inertias_and_beam_properties_are_refused_at_their_field() {
    for (from, to, needle, path) in [
        ("mass: m", "mass: -m", "mass:", "`bodies.c.mass` = -2"),
        (
            "inertia: j",
            "inertia: 0 * j",
            "inertia:",
            "`bodies.c.inertia` = 0",
        ),
        (
            "length: 40",
            "length: -40",
            "    length:",
            "`beams.r.length` = -40",
        ),
        (
            "bending_stiffness: 1.0e+6",
            "bending_stiffness: 0",
            "bending_stiffness",
            "`beams.r.bending_stiffness` = 0",
        ),
        (
            "mass_per_length: 60",
            "mass_per_length: -60",
            "mass_per_length",
            "`beams.r.mass_per_length` = -60",
        ),
    ] {
        let text = edit(BASE, from, to);
        only(
            &text,
            needle,
            &["at the nominal values", path, "finite and > 0"],
        );
    }
    // A negative stiffness, at each element's line.
    let text = edit(BASE, "value: 8.0e+5", "value: -8.0e+5");
    let r = report(&text);
    expect(
        &r,
        &text,
        "front: {kind",
        &["`elements.front.k` = -800000", "finite and >= 0"],
    );
    expect(&r, &text, "rear: {kind", &["`elements.rear.k` = -800000"]);
    assert_eq!(r.lines().count(), 2, "{r}");
}

#[test]
fn an_unrestrained_dof_is_named() {
    // A free body: nothing holds its vertical DOF.
    let text = edit(BASE, "beams:", "  free: {mass: 1, dofs: [z]}\nbeams:");
    only(
        &text,
        "free:",
        &["bodies.free", "DOF `z_free` is not restrained", "singular"],
    );
    // Both elements at one point: the pitch is free.
    let text = edit(BASE, "from: c.rear", "from: c.front");
    only(
        &text,
        "  c:",
        &[
            "bodies.c",
            "DOF `beta_c` is not restrained",
            "two different points",
        ],
    );
    // Every unrestrained DOF is named, not only the first.
    let text = edit(
        BASE,
        "beams:",
        "  free: {mass: 1, dofs: [z]}\n  loose: {mass: 1, dofs: [z]}\nbeams:",
    );
    let r = report(&text);
    expect(&r, &text, "free:", &["DOF `z_free`"]);
    expect(&r, &text, "loose:", &["DOF `z_loose`"]);
    assert_eq!(r.lines().count(), 2, "{r}");
}

#[test]
fn unknown_fields_list_the_allowed_ones() {
    let text = edit(BASE, "    mass: m", "    mas: m");
    let r = report(&text);
    expect(
        &r,
        &text,
        "mas: m",
        &[
            "bodies.c",
            "unknown field `mas`",
            "allowed: mass, inertia, dofs, points, doc",
        ],
    );
    // A block mapping starts at its first field: the missing field is reported there.
    expect(&r, &text, "mas: m", &["bodies.c: missing field `mass`"]);
    let text = edit(BASE, "k: k, profile", "k: k, damping: 5, profile");
    only(
        &text,
        "front: {kind",
        &[
            "elements.front",
            "unknown field `damping`",
            "allowed: kind, from, to, profile, k, c, preload",
        ],
    );
    let text = format!("{BASE}extras: 1\n");
    only(
        &text,
        "extras:",
        &[
            "description: unknown field `extras`",
            "allowed: format, name, doc, parameters, bodies, beams, moving, sensors",
        ],
    );
    let text = edit(BASE, "kind: harmonic", "kind: sinus");
    only(
        &text,
        "bumps:",
        &[
            "profiles.bumps.kind",
            "`sinus`",
            "allowed: generated",
            "harmonic",
        ],
    );
}

#[test]
fn a_wrong_or_missing_format_version_is_refused() {
    let text = edit(BASE, "format: 1", "format: 2");
    only(
        &text,
        "format:",
        &["format: this program reads format 1, found `2`"],
    );
    let text = edit(BASE, "format: 1\n", "");
    only(&text, "name: probe", &["missing field `format`"]);
}

#[test]
fn column_name_collisions_name_both_producers() {
    // A sensor named like a body: `z_c`, `z_c_v`, `z_c_a` twice, one problem.
    let text = edit(
        BASE,
        "  mid: {on: r, x: 20}",
        "  mid: {on: r, x: 20}\n  c: {on: r, x: 10}",
    );
    only(
        &text,
        "c: {on: r",
        &[
            "column `z_c`",
            "body `c`",
            "sensor `c`",
            "also `z_c_v`, `z_c_a`",
            "rename one",
        ],
    );
    // A body `c_v` declared after `c`: its `z_c_v` is `c`'s vertical velocity.
    let text = edit(BASE, "beams:", "  c_v: {mass: 1, dofs: [z]}\nbeams:");
    let r = report(&text);
    expect(
        &r,
        &text,
        "c_v: {mass",
        &["column `z_c_v`", "body `c`", "body `c_v`"],
    );
}

#[test]
fn outputs_name_existing_columns() {
    let text = edit(BASE, "outputs: [z_p1,", "outputs: [z_nope, z_p1,");
    only(
        &text,
        "outputs:",
        &[
            "outputs: no column `z_nope`",
            "available: z_p1, z_mid, z_mid_v, z_mid_a, eta_front, f_front, d_front, f_rear, d_rear",
        ],
    );
    let text = edit(BASE, "outputs: [z_p1,", "outputs: [z_c, z_p1,");
    only(
        &text,
        "outputs:",
        &["`z_c` is a body DOF column, always stored"],
    );
}

#[test]
fn counts_fixed_for_every_sample() {
    let text = edit(BASE, "modes: n", "modes: 2 * m");
    let r = report(&text);
    expect(
        &r,
        &text,
        "modes:",
        &[
            "beams.r.modes",
            "a count must be the same for every sample",
            "`m` varies",
        ],
    );
    let text = edit(BASE, "value: 4}", "value: 4.5}");
    only(
        &text,
        "modes:",
        &["beams.r.modes", "an integer in [1, 1e7], found 4.5"],
    );
}

#[test]
fn a_profile_lies_under_a_moving_point() {
    let text = edit(BASE, "to: g1, k: k}", "to: ground, k: k, profile: bumps}");
    only(
        &text,
        "rear: {kind",
        &[
            "elements.rear.profile",
            "a profile lies under a moving point",
            "`to` must be one (p1, g1)",
        ],
    );
}

/// Two independent problems give two lines, in file order, whatever order they are found in.
#[test]
fn all_problems_of_a_stage_are_reported_at_once_in_line_order() {
    // Names: an unused parameter (found last, at the end of compilation) and an unknown
    // profile (found among the elements) and an unknown body.
    let text = edit(
        BASE,
        "  v: {unit",
        "  spare: {unit: N/m, value: 9}\n  v: {unit",
    );
    let text = edit(&text, "profile: bumps", "profile: bump");
    let text = edit(&text, "from: c.rear", "from: cc.rear");
    let r = report(&text);
    let lines: Vec<&str> = r.lines().collect();
    assert_eq!(lines.len(), 3, "{r}");
    expect(&r, &text, "spare:", &["never used"]);
    expect(&r, &text, "front: {kind", &["unknown profile `bump`"]);
    expect(&r, &text, "rear: {kind", &["unknown point `cc.rear`"]);
    let numbers: Vec<usize> = lines
        .iter()
        .map(|l| l.split(':').nth(1).unwrap().parse().unwrap())
        .collect();
    assert!(numbers.windows(2).all(|w| w[0] < w[1]), "{r}");
    // Shapes: two unknown fields in different sections.
    let text = edit(BASE, "    dofs:", "    dof: [z]\n    dofs:");
    let text = edit(&text, "wavelength: 2}", "wavelength: 2, phase_deg: 3}");
    let r = report(&text);
    assert_eq!(r.lines().count(), 2, "{r}");
    expect(&r, &text, "dof: [z]", &["unknown field `dof`"]);
    expect(&r, &text, "bumps:", &["unknown field `phase_deg`"]);
    // Values at the nominal parameters: a negative mass and a zero beam stiffness.
    let text = edit(BASE, "mass: m", "mass: -m");
    let text = edit(&text, "bending_stiffness: 1.0e+6", "bending_stiffness: 0");
    let r = report(&text);
    assert_eq!(r.lines().count(), 2, "{r}");
    expect(&r, &text, "mass: -m", &["`bodies.c.mass` = -2"]);
    expect(
        &r,
        &text,
        "bending_stiffness",
        &["`beams.r.bending_stiffness` = 0"],
    );
}

/// A message quoting text with a line break stays on one line of the report.
#[test]
fn one_problem_is_one_line() {
    let text = edit(BASE, "mass: m", "mass: \"m\\n+ 1 $\"");
    let r = report(&text);
    assert_eq!(r.lines().count(), 1, "{r}");
    assert!(r.contains("`m\\n+ 1 $`"), "{r}");
}

/// A flow mapping left open is reported at its `{` (file, line and column), not at the next
/// key where the parser stops; so is a flow list closed by the wrong bracket.
#[test]
fn an_unclosed_flow_collection_is_reported_where_it_opens() {
    let text = edit(
        BASE,
        "m: {unit: kg, nominal: 2, range: [1, 3]}",
        "m: {unit: kg, nominal: 2, range: [1, 3]",
    );
    let r = report(&text);
    let line = line_of(&text, "m: {unit: kg");
    assert!(
        r.starts_with(&format!(
            "bad.yaml:{line}:6: not valid YAML: unclosed flow mapping `{{` opened here"
        )),
        "{r}"
    );
    assert_eq!(r.lines().count(), 1, "{r}");
    let text = edit(BASE, "range: [1, 3]}", "range: [1, 3}");
    let r = report(&text);
    assert!(
        r.starts_with(&format!(
            "bad.yaml:{line}:36: not valid YAML: unclosed flow sequence `[` opened here"
        )),
        "{r}"
    );
}

#[test]
fn a_profiles_interpolation_is_linear_by_default_cubic_on_request_and_nothing_else() {
    use mbd_system::model::ModelProfile;
    use mbd_system::schema::Interpolation;
    let generated = |extra: &str| {
        edit(
            BASE,
            "  bumps: {kind: harmonic, amplitude: 1.0e-3, wavelength: 2}\n",
            &format!(
                "  bumps:\n    kind: generated\n    psd: {{iso8608: C}}\n    wavelengths: [0.5, 90.0]\n{extra}"
            ),
        )
    };
    for (extra, expected) in [
        ("", Interpolation::Linear),
        ("    interpolation: linear\n", Interpolation::Linear),
        ("    interpolation: cubic\n", Interpolation::Cubic),
    ] {
        let system = compiles(&generated(extra));
        let model = system.instantiate(&system.nominal()).unwrap();
        assert_eq!(
            model.profiles,
            vec![ModelProfile::Generated {
                interpolation: expected
            }],
            "{extra}"
        );
    }
    let text = generated("    interpolation: quadratic\n");
    only(
        &text,
        "interpolation: quadratic",
        &[
            "profiles.bumps.interpolation",
            "`quadratic`",
            "allowed: linear, cubic (default linear)",
        ],
    );
    // An analytic profile has no points to interpolate.
    let text = edit(
        BASE,
        "wavelength: 2}",
        "wavelength: 2, interpolation: cubic}",
    );
    only(
        &text,
        "bumps:",
        &["profiles.bumps", "unknown field `interpolation`"],
    );
}

#[test]
fn an_fra_track_class_is_read_as_its_spectrum_and_a_bad_class_or_irregularity_is_refused() {
    use mbd_system::schema::fra::{fra_psd, FraIrregularity};
    use mbd_system::system::Profile;
    let generated = |fra: &str| {
        edit(
            BASE,
            "  bumps: {kind: harmonic, amplitude: 1.0e-3, wavelength: 2}\n",
            &format!(
                "  bumps:\n    kind: generated\n    psd:\n      fra: {fra}\n    wavelengths: [2.0, 100.0]\n"
            ),
        )
    };
    for (text, class, kind) in [
        (
            "{class: 5, irregularity: vertical}",
            5,
            FraIrregularity::Vertical,
        ),
        (
            "{class: 1, irregularity: alignment}",
            1,
            FraIrregularity::Alignment,
        ),
        (
            "{class: 6, irregularity: cross_level}",
            6,
            FraIrregularity::CrossLevel,
        ),
    ] {
        let system = compiles(&generated(text));
        let Profile::Generated { psd, .. } = &system.profiles[0] else {
            panic!("generated")
        };
        assert_eq!(psd, &fra_psd(class, kind).unwrap(), "{text}");
    }
    let allowed = "allowed: 1, 2, 3, 4, 5, 6";
    for bad in ["7", "0", "2.5"] {
        let text = generated(&format!("{{class: {bad}, irregularity: vertical}}"));
        only(
            &text,
            "fra:",
            &[&format!("profiles.bumps.psd.fra.class: {bad}"), allowed],
        );
    }
    let text = generated("{class: 5, irregularity: gauge}");
    only(
        &text,
        "fra:",
        &[
            "profiles.bumps.psd.fra.irregularity",
            "`gauge`",
            "allowed: vertical, alignment, cross_level",
        ],
    );
    let text = generated("{class: 5}");
    only(
        &text,
        "fra:",
        &["profiles.bumps.psd.fra", "missing field `irregularity`"],
    );
    let text = generated("{class: 5, irregularity: vertical, k: 0.3}");
    only(
        &text,
        "fra:",
        &["unknown field `k`", "allowed: class, irregularity"],
    );
}

#[test]
fn indices_from_is_read_and_a_negative_or_non_numeric_time_is_refused_at_its_line() {
    assert_eq!(
        compiles(BASE).indices_from,
        0.0,
        "absent: every point is read"
    );
    let with = |v: &str| format!("{BASE}indices_from: {v}\n");
    assert_eq!(compiles(&with("0.25")).indices_from, 0.25);
    only(
        &with("-0.1"),
        "indices_from",
        &["indices_from", "-0.1", ">= 0"],
    );
    let text = with("soon");
    expect(&report(&text), &text, "indices_from", &["indices_from"]);
}
