//! The vehicle-track description compiles to the layout of today's public schema.

#[test]
fn vehicle_track_description_gives_the_public_columns() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../systems/vtcd.yaml"
    ))
    .unwrap();
    let s = match mbd_system::load_str(&text, "systems/vtcd.yaml", &Default::default()) {
        Ok(s) => s,
        Err(d) => panic!("{d}"),
    };
    let cols: Vec<&str> = s.channels.iter().map(|c| c.name.as_str()).collect();
    println!("{cols:?}");
    assert_eq!(s.sampled_names().len(), 14);
    assert_eq!(cols.len(), 42);
    for g in &s.assembly {
        println!("{g:?}");
    }
}

/// A field out of its domain names the sampled parameters it is computed from, through
/// derived parameters: the car-body mass `m_c / 2` comes from `m_c` alone, the static wheel
/// load `W` from the three masses; a fixed parameter contributes none.
#[test]
fn a_field_out_of_its_domain_names_the_sampled_parameters_it_comes_from() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../systems/vtcd.yaml"
    ))
    .unwrap();
    let s = mbd_system::load_str(&text, "systems/vtcd.yaml", &Default::default())
        .unwrap_or_else(|d| panic!("{d}"));
    let at = |name: &str, value: f64| {
        let mut design = s.nominal();
        assert!(design.set(name, value), "{name} is sampled");
        s.instantiate(&design).unwrap_err()
    };
    let e = at("m_c", -1.0);
    assert_eq!((e.path.as_str(), e.value), ("bodies.c.mass", -0.5));
    assert_eq!(e.sources, ["m_c"]);
    let e = at("m_c", 1e308);
    assert_eq!(e.path, "parameters.W");
    assert_eq!(e.sources, ["m_c", "m_t", "m_w"]);
    let w = s.parameter("W").unwrap();
    let g = s.parameter("g").unwrap();
    assert_eq!(s.sampled_sources([w, g]), ["m_c", "m_t", "m_w"]);
    assert!(s.sampled_sources([g]).is_empty());
}
