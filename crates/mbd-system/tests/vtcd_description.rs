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
