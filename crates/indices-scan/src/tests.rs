//! The polars aggregation against the plain-Rust fold on the same data, and bad input named by
//! file, sample and column.

use super::*;
use pino_data::{Column, Table};
use pino_indices::{IndexParams, Record};

const DT: f64 = 1e-3;

/// Named columns of one synthetic record.
type Columns = Vec<(String, Vec<f64>)>;
/// An edit of a sample's columns before writing (to plant NaNs, drop columns, ...).
type Edit<'a> = &'a dyn Fn(i64, &mut Columns);

/// A deterministic record of `n` rows for sample `id`: sinusoids and a few spikes in every
/// signal, different per sample.
fn record_columns(id: i64, n: usize) -> Vec<(String, Vec<f64>)> {
    let s = id as f64;
    let wave = |k: usize, f: f64, a: f64, ph: f64| {
        a * (2.0 * std::f64::consts::PI * f * k as f64 * DT + ph).sin()
    };
    let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
    for (i, name) in pino_indices::columns::P.iter().enumerate() {
        let v = (0..n)
            .map(|k| {
                70e3 + wave(k, 20.0 + i as f64, 8e3 + 100.0 * s, 0.3 * s)
                    + if k == 37 * (i + 1) { 25e3 } else { 0.0 }
            })
            .collect();
        cols.push((name.to_string(), v));
    }
    let z: Vec<f64> = (0..n)
        .map(|k| wave(k, 1.5, 0.2, s) + wave(k, 9.0, 0.05, 0.0))
        .collect();
    let b: Vec<f64> = (0..n)
        .map(|k| wave(k, 2.5, 0.01, s) - if k == 100 { 0.07 } else { 0.0 })
        .collect();
    cols.push((pino_indices::columns::Z_C_A.into(), z));
    cols.push((pino_indices::columns::BETA_C_A.into(), b));
    for (i, name) in pino_indices::columns::Z_T_A.iter().enumerate() {
        cols.push((
            name.to_string(),
            (0..n).map(|k| wave(k, 7.0 + i as f64, 1.5, s)).collect(),
        ));
    }
    for (i, name) in pino_indices::columns::Z_R.iter().enumerate() {
        cols.push((
            name.to_string(),
            (0..n)
                .map(|k| 0.9e-3 + wave(k, 30.0, 0.2e-3 * (1.0 + i as f64), s))
                .collect(),
        ));
    }
    cols
}

fn params_of(id: i64) -> [f64; 14] {
    let mut p = vtcd::params::SampleParams::NOMINAL.to_array();
    p[9] = 8.0 + 0.25 * id as f64; // l_c
    p[0] *= 1.0 + 0.01 * id as f64; // m_c
    p
}

/// Writes a simulation file of samples `ids` (`n` rows each) with the indices' columns.
fn write_sim(path: &Path, ids: &[i64], n: usize, edit: Edit) {
    let mut t = Table::default();
    let mut sid = Vec::new();
    let mut time = Vec::new();
    let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
    for &id in ids {
        let mut c = record_columns(id, n);
        edit(id, &mut c);
        let rows = c[0].1.len();
        sid.extend(std::iter::repeat_n(id, rows));
        time.extend((0..rows).map(|k| k as f64 * DT));
        if cols.is_empty() {
            cols = c;
        } else {
            for (dst, (_, src)) in cols.iter_mut().zip(c) {
                dst.1.extend(src);
            }
        }
    }
    if cols.is_empty() {
        cols = record_columns(0, 0);
    }
    t.push(schema::SAMPLE_ID, Column::I64(sid)).unwrap();
    t.push(schema::TIME, Column::F64(time)).unwrap();
    for (name, v) in cols {
        t.push(&name, Column::F64(v)).unwrap();
    }
    pino_data::write_parquet(path, &t).unwrap();
}

fn write_params(path: &Path, ids: &[i64]) {
    let mut t = Table::default();
    t.push(schema::SAMPLE_ID, Column::I64(ids.to_vec()))
        .unwrap();
    t.push(
        schema::SPLIT,
        Column::Str(
            ids.iter()
                .map(|&i| if i < 3 { "train" } else { "test" }.to_owned())
                .collect(),
        ),
    )
    .unwrap();
    for (j, name) in schema::PARAMETERS.iter().enumerate() {
        t.push(
            name,
            Column::F64(ids.iter().map(|&i| params_of(i)[j]).collect()),
        )
        .unwrap();
    }
    pino_data::write_parquet(path, &t).unwrap();
}

struct Fixture {
    dir: tempfile::TempDir,
    params: PathBuf,
    files: Vec<PathBuf>,
}

fn fixture(edit: Edit) -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("params.parquet");
    write_params(&params, &[0, 1, 2, 3, 4, 5]);
    let files = vec![dir.path().join("a.parquet"), dir.path().join("b.parquet")];
    write_sim(&files[0], &[0, 1, 2], 1500, edit);
    // Sample 5 is absent (a failed simulation).
    write_sim(&files[1], &[3, 4], 1500, edit);
    Fixture { dir, params, files }
}

fn cfg(fraction: f64) -> IndexConfig {
    IndexParams {
        window_start_fraction: fraction,
        ..IndexParams::default()
    }
    .validate()
    .unwrap()
}

#[test]
fn the_polars_aggregation_equals_the_plain_rust_fold() {
    let fx = fixture(&|_, _| {});
    let c = cfg(0.1);
    let got = compute_all(&fx.params, &fx.files, &c, &|_| {}).unwrap();
    assert_eq!(got.rows.len(), 5);
    assert_eq!(got.absent, 1);
    assert_eq!(
        got.rows.iter().map(|r| r.id).collect::<Vec<_>>(),
        vec![0, 1, 2, 3, 4]
    );
    for row in &got.rows {
        let cols = record_columns(row.id, 1500);
        let s = |name: &str| cols.iter().find(|(n, _)| n == name).unwrap().1.as_slice();
        let rec = Record {
            dt: DT,
            p: pino_indices::columns::P.map(s),
            z_c_a: s(pino_indices::columns::Z_C_A),
            beta_c_a: s(pino_indices::columns::BETA_C_A),
            z_t_a: pino_indices::columns::Z_T_A.map(s),
            z_r: pino_indices::columns::Z_R.map(s),
        };
        let first = c.first_index(1500);
        assert_eq!(first, 150);
        let win = rec.tail(first);
        let p = params_of(row.id);
        let w = vtcd::vehicle::Vehicle::new(&vtcd::params::SampleParams::from_array(p), 9.81).w;
        // The polars extremes are the plain fold's, exactly.
        let plain = Aggregates::fold(&win, p[9]).unwrap();
        let windows = [(row.id, first as f64 * DT)];
        let ext = aggregate(&fx.files, &windows, &|_| PathBuf::new()).unwrap()[&row.id];
        assert_eq!(ext.n, plain.n);
        assert_eq!(ext.p_max, plain.p_max);
        assert_eq!(ext.p_min, plain.p_min);
        assert_eq!(ext.bogie_abs_max, plain.bogie_abs_max);
        assert_eq!(ext.z_r_max, plain.z_r_max);
        // And the indices of the stage's path against `pino_indices::compute`.
        let want = pino_indices::compute(&win, p[9], w, &c).unwrap();
        // Same arithmetic in the same order: the same bits.
        assert_eq!(row.indices, want);
        assert_eq!(row.indices.window_s, want.window_s);
        // The spike of p_1 at row 37 is before the window; p_2's at 74 too; p_4's at 148.
        assert!(row.indices.peak_wheel_rail_force_kn < 70.0 + 25.0);
    }
    // Deterministic bytes, and the table's layout.
    write_outputs(fx.dir.path(), &got.rows, &c).unwrap();
    let a = std::fs::read(fx.dir.path().join("indices.parquet")).unwrap();
    write_outputs(fx.dir.path(), &got.rows, &c).unwrap();
    assert_eq!(
        a,
        std::fs::read(fx.dir.path().join("indices.parquet")).unwrap()
    );
    let t = pino_data::read_parquet(&fx.dir.path().join("indices.parquet"), None).unwrap();
    let names: Vec<&str> = t.names().collect();
    assert_eq!(names.len(), 2 + 14 + 14 + 3);
    assert_eq!(names[16], "peak_wheel_rail_force_kn");
    assert_eq!(t.str("split").unwrap()[3], "test");
    let json = std::fs::read_to_string(fx.dir.path().join("indices.json")).unwrap();
    assert!(
        json.contains("\"sperling.segment_s\": \"whole window\""),
        "{json}"
    );
}

#[test]
fn a_missing_column_names_file_and_column() {
    let fx = fixture(&|_, _| {});
    write_sim(&fx.files[1], &[3, 4], 100, &|_, c| {
        c.retain(|(n, _)| n != "p_3")
    });
    let e = compute_all(&fx.params, &fx.files, &cfg(0.0), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.parquet") && e.contains("missing column `p_3`"),
        "{e}"
    );
}

#[test]
fn nan_names_file_sample_and_column() {
    // In a signal of the polars pass (the row counted from the window's first, row 150) ...
    let fx = fixture(&|id, c| {
        if id == 4 {
            c.iter_mut().find(|(n, _)| n == "z_r2").unwrap().1[900] = f64::NAN;
        }
    });
    let e = compute_all(&fx.params, &fx.files, &cfg(0.1), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.parquet")
            && e.contains("sample 4")
            && e.contains("`z_r2`")
            && e.contains("row 750 of the window")
            && e.contains("NaN"),
        "{e}"
    );
    // ... and in one of the spectral pass (with the row).
    let fx = fixture(&|id, c| {
        if id == 1 {
            c.iter_mut().find(|(n, _)| n == "beta_c_a").unwrap().1[10] = f64::INFINITY;
        }
    });
    let e = compute_all(&fx.params, &fx.files, &cfg(0.0), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.parquet")
            && e.contains("sample 1")
            && e.contains("`beta_c_a`")
            && e.contains("row 10"),
        "{e}"
    );
    // Before the window a NaN does not matter.
    let fx = fixture(&|id, c| {
        if id == 1 {
            c.iter_mut().find(|(n, _)| n == "p_1").unwrap().1[10] = f64::NAN;
        }
    });
    compute_all(&fx.params, &fx.files, &cfg(0.1), &|_| {}).unwrap();
}

#[test]
fn empty_and_inconsistent_samples_are_refused() {
    // A sample of one row.
    let fx = fixture(&|_, _| {});
    write_sim(&fx.files[1], &[3, 4], 1500, &|id, c| {
        if id == 3 {
            for (_, v) in c.iter_mut() {
                v.truncate(1);
            }
        }
    });
    let e = compute_all(&fx.params, &fx.files, &cfg(0.0), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.parquet") && e.contains("sample 3") && e.contains("1 points"),
        "{e}"
    );
    // Files without a single row.
    let fx = fixture(&|_, _| {});
    for f in &fx.files {
        write_sim(f, &[], 10, &|_, _| {});
    }
    let e = compute_all(&fx.params, &fx.files, &cfg(0.0), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("no simulated sample"), "{e}");
    // A sample in two files; a sample unknown to params.parquet.
    let fx = fixture(&|_, _| {});
    write_sim(&fx.files[1], &[2, 3], 200, &|_, _| {});
    let e = compute_all(&fx.params, &fx.files, &cfg(0.0), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("sample 2 is also in") && e.contains("a.parquet"),
        "{e}"
    );
    write_sim(&fx.files[1], &[3, 9], 200, &|_, _| {});
    let e = compute_all(&fx.params, &fx.files, &cfg(0.0), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("sample 9 is not in params.parquet"), "{e}");
}
