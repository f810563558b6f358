//! A process that declares its origin writes it into every file, streamed or not, and the
//! same bytes on a rerun. (Its own test binary: the origin is per process.)

use pino_data::metadata::{
    read_metadata, set_origin, Origin, COLUMN_UNITS_KEY, PARAMS_KEY, STAGE_KEY, UNIT_KEY, VERSION,
    VERSION_KEY,
};
use pino_data::units::Units;
use pino_data::{schema, write_parquet, Column, StreamWriter, Table};

/// A table with a system's column (`p_1`), its unit carried by the table.
fn table() -> Table {
    let units = Units::default().with([("p_1", "N")]).unwrap();
    let mut t = Table::default().with_units(units);
    t.push(schema::SAMPLE_ID, Column::I64(vec![0, 0])).unwrap();
    t.push(schema::TIME, Column::F64(vec![0.0, 1e-3])).unwrap();
    t.push("p_1", Column::F64(vec![7e4, 7.1e4])).unwrap();
    t
}

#[test]
fn declared_origin_is_in_every_file() {
    let params = serde_json::json!({"duration": 0.5, "start": "equilibrium"});
    set_origin(Origin::stage_unit("simulate", 1, 2, &params)).unwrap();
    // The same origin again is fine, another one is refused.
    set_origin(Origin::stage_unit("simulate", 1, 2, &params)).unwrap();
    let e = set_origin(Origin::stage_unit("simulate", 0, 2, &params))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("`simulate#1`") && e.contains("`simulate#0`"),
        "{e}"
    );

    let dir = tempfile::tempdir().unwrap();
    let (a, b, s) = (
        dir.path().join("a.parquet"),
        dir.path().join("b.parquet"),
        dir.path().join("s.parquet"),
    );
    write_parquet(&a, &table()).unwrap();
    write_parquet(&b, &table()).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let mut w = StreamWriter::create(&s, &table()).unwrap();
    w.write(&table()).unwrap();
    w.finish().unwrap();
    for f in [&a, &s] {
        let m = read_metadata(f).unwrap();
        let kv = &m.key_value;
        assert_eq!(kv[STAGE_KEY], "simulate");
        assert_eq!(kv[UNIT_KEY], "simulate#1");
        assert_eq!(kv[VERSION_KEY], VERSION);
        let back: serde_json::Value = serde_json::from_str(&kv[PARAMS_KEY]).unwrap();
        assert_eq!(back, params);
        assert_eq!(
            kv[COLUMN_UNITS_KEY],
            r#"{"p_1":"N","sample_id":"1","t":"s"}"#
        );
        assert_eq!(m.column_units[2], ("p_1".to_owned(), Some("N".to_owned())));
    }
}

#[test]
fn a_file_written_for_a_request_names_its_own_origin_beside_the_process() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.parquet");
    let params = serde_json::json!({"design": {"k_s": 4.0e5}, "excitation": {"kind": "seed"}});
    let origin = Origin::stage_unit("explore", 0, 1, &params);
    pino_data::write_parquet_from(&path, &table(), &origin).unwrap();
    let kv = read_metadata(&path).unwrap().key_value;
    assert_eq!(kv[STAGE_KEY], "explore");
    assert_eq!(kv[UNIT_KEY], "explore");
    assert_eq!(kv[PARAMS_KEY], params.to_string());
    assert_eq!(
        pino_data::read_parquet(&path, None).unwrap().columns(),
        table().columns()
    );
}
