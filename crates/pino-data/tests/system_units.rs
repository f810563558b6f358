//! Units travel with the tables: two systems whose columns share a name with different units
//! are written by one process, each file with its own system's units, and a column no unit is
//! known for is refused by name.

use mbd_system::{System, SystemSource};
use pino_data::metadata::{read_metadata, COLUMN_UNITS_KEY};
use pino_data::{schema, write_parquet, Column, StreamWriter, Table};

const QUARTER_CAR: &str = include_str!("../../../systems/quarter-car.yaml");

fn compile(file: &str, text: &str) -> System {
    SystemSource {
        file: file.into(),
        text: text.into(),
        values: Default::default(),
    }
    .compile()
    .unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// A one-row params table of `system`, carrying its units.
fn params(system: &System) -> Table {
    let mut t = Table::default().with_units(pino_data::system::units_of(system).unwrap());
    t.push(schema::SAMPLE_ID, Column::I64(vec![0])).unwrap();
    for name in system.sampled_names() {
        t.push(name, Column::F64(vec![1.0])).unwrap();
    }
    t
}

/// The `unit` field metadata of column `name` of the file at `path`.
fn unit_in_file(path: &std::path::Path, name: &str) -> String {
    read_metadata(path)
        .unwrap()
        .column_units
        .into_iter()
        .find(|(n, _)| n == name)
        .and_then(|(_, u)| u)
        .unwrap_or_else(|| panic!("{}: no unit for `{name}`", path.display()))
}

#[test]
fn two_systems_write_their_own_units_from_one_process() {
    let kmh = compile("quarter-car.yaml", QUARTER_CAR);
    let text = QUARTER_CAR.replace("v_kmh: {unit: km/h", "v_kmh: {unit: m/s");
    assert_ne!(text, QUARTER_CAR, "the variant changes the speed's unit");
    let ms = compile("quarter-car-ms.yaml", &text);

    let dir = tempfile::tempdir().unwrap();
    let (a, b, s) = (
        dir.path().join("kmh.parquet"),
        dir.path().join("ms.parquet"),
        dir.path().join("ms-stream.parquet"),
    );
    write_parquet(&a, &params(&kmh)).unwrap();
    write_parquet(&b, &params(&ms)).unwrap();
    let mut w = StreamWriter::create(&s, &params(&ms)).unwrap();
    // Rows without units of their own go to the file with the template's.
    let mut row = Table::default();
    row.push(schema::SAMPLE_ID, Column::I64(vec![1])).unwrap();
    for name in ms.sampled_names() {
        row.push(name, Column::F64(vec![2.0])).unwrap();
    }
    w.write(&row).unwrap();
    w.finish().unwrap();

    assert_eq!(unit_in_file(&a, "v_kmh"), "km/h");
    assert_eq!(unit_in_file(&b, "v_kmh"), "m/s");
    assert_eq!(unit_in_file(&s, "v_kmh"), "m/s");
    assert_eq!(unit_in_file(&a, "k_s"), "N/m");
    assert_eq!(unit_in_file(&b, "m_s"), "kg");
    let json = |p: &std::path::Path| read_metadata(p).unwrap().key_value[COLUMN_UNITS_KEY].clone();
    assert!(json(&a).contains(r#""v_kmh":"km/h""#), "{}", json(&a));
    assert!(json(&b).contains(r#""v_kmh":"m/s""#), "{}", json(&b));
    // One system's units do not leak into the other's tables, nor into a bare one.
    assert_eq!(params(&kmh).unit("v_kmh"), Some("km/h"));
    assert_eq!(Table::default().unit("v_kmh"), None);
}

#[test]
fn a_column_without_a_unit_is_refused_by_name() {
    let system = compile("quarter-car.yaml", QUARTER_CAR);
    let dir = tempfile::tempdir().unwrap();
    let mut t = params(&system);
    t.push("mystery_column", Column::F64(vec![1.0])).unwrap();
    let path = dir.path().join("p.parquet");
    let e = write_parquet(&path, &t).unwrap_err();
    assert!(
        matches!(&e, pino_data::Error::NoUnit { column, .. } if column == "mystery_column"),
        "{e:?}"
    );
    assert!(
        e.to_string().contains("`mystery_column` has no unit"),
        "{e}"
    );
    assert!(!path.exists());
    // The system's columns in a table that does not carry its units are refused the same way.
    let mut bare = Table::default();
    bare.push("v_kmh", Column::F64(vec![72.0])).unwrap();
    let e = write_parquet(&path, &bare).unwrap_err().to_string();
    assert!(e.contains("`v_kmh` has no unit"), "{e}");
}
