//! The scan on small synthetic datasets of the repository's descriptions: the polars
//! aggregation against the plain-Rust fold (vehicle-track), the simple indices against hand
//! computations (each statistic with `subtract` and `divide`; the quarter car's and the
//! bridge's own), a description with no index, and bad input named by file, sample and column.

use super::*;
use mbd_system::system::ParamSource;
use mbd_system::SystemSource;
use mbd_test_models::vehicle_track;
use pino_data::{Column, Table};
use pino_indices::{IndexParams, Record};

const DT: f64 = 1e-3;
const VTCD: &str = include_str!("../../../systems/vtcd.yaml");
const QUARTER_CAR: &str = include_str!("../../../systems/quarter-car.yaml");
const BRIDGE: &str = include_str!("../../../systems/bridge.yaml");

/// Named columns of one synthetic record.
type Columns = Vec<(String, Vec<f64>)>;
/// The columns of sample `id` with `n` rows.
type Signals<'a> = &'a dyn Fn(i64, usize) -> Columns;
/// An edit of a sample's columns before writing (to plant NaNs, drop columns, ...).
type Edit<'a> = &'a dyn Fn(i64, &mut Columns);

/// Compiles a description text.
fn compile(file: &str, text: &str) -> System {
    SystemSource {
        file: file.into(),
        text: text.into(),
        values: Default::default(),
    }
    .compile()
    .unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// `text` with its `indices:` section (the last one of the quarter car's description)
/// replaced by `indices` (empty: no section).
fn with_indices(text: &str, indices: &str) -> String {
    let at = text.find("\nindices:\n").expect("an indices section");
    format!("{}\n{indices}", &text[..at])
}

/// The sampled parameters of sample `id`: nominal values, with `l_c` and `m_c` (vehicle-track)
/// or every parameter (other descriptions) varied by sample.
fn params_of(system: &System, id: i64) -> mbd_system::Sampled {
    let values: Vec<f64> = system
        .sampled()
        .into_iter()
        .map(|i| {
            let p = &system.parameters[i];
            let ParamSource::Sampled { nominal, .. } = p.source else {
                unreachable!("sampled")
            };
            match (system.railway.is_some(), p.name.as_str()) {
                (true, "l_c") => 8.0 + 0.25 * id as f64,
                (true, "m_c") => nominal * (1.0 + 0.01 * id as f64),
                (true, _) => nominal,
                (false, _) => nominal * (1.0 + 0.01 * id as f64),
            }
        })
        .collect();
    system.sampled_values(values).unwrap()
}

fn wave(k: usize, f: f64, a: f64, ph: f64) -> f64 {
    a * (2.0 * std::f64::consts::PI * f * k as f64 * DT + ph).sin()
}

/// A deterministic record of `n` rows for sample `id` of the vehicle-track description:
/// sinusoids and a few spikes in every signal, different per sample, under the column names of
/// its railway binding.
fn railway_columns(id: i64, n: usize) -> Columns {
    let system = compile("vtcd.yaml", VTCD);
    let r = IndexSet::of(&system).railway.unwrap();
    let s = id as f64;
    let mut cols: Columns = Vec::new();
    for (i, name) in r.p.iter().enumerate() {
        let v = (0..n)
            .map(|k| {
                70e3 + wave(k, 20.0 + i as f64, 8e3 + 100.0 * s, 0.3 * s)
                    + if k == 37 * (i + 1) { 25e3 } else { 0.0 }
            })
            .collect();
        cols.push((name.clone(), v));
    }
    let z: Vec<f64> = (0..n)
        .map(|k| wave(k, 1.5, 0.2, s) + wave(k, 9.0, 0.05, 0.0))
        .collect();
    let b: Vec<f64> = (0..n)
        .map(|k| wave(k, 2.5, 0.01, s) - if k == 100 { 0.07 } else { 0.0 })
        .collect();
    cols.push((r.z_c_a.clone(), z));
    cols.push((r.beta_c_a.clone(), b));
    for (i, name) in r.z_t_a.iter().enumerate() {
        cols.push((
            name.clone(),
            (0..n).map(|k| wave(k, 7.0 + i as f64, 1.5, s)).collect(),
        ));
    }
    for (i, name) in r.z_r.iter().enumerate() {
        cols.push((
            name.clone(),
            (0..n)
                .map(|k| 0.9e-3 + wave(k, 30.0, 0.2e-3 * (1.0 + i as f64), s))
                .collect(),
        ));
    }
    cols
}

/// The quarter car's index channels: body acceleration, suspension deflection (sample 2
/// beyond the 8 cm bump stop) and tyre force about its static value.
fn quarter_car_columns(id: i64, n: usize) -> Columns {
    let system = compile("quarter-car.yaml", QUARTER_CAR);
    let v = system.values(&params_of(&system, id)).unwrap();
    let static_load = (v[system.parameter("m_s").unwrap()] + v[system.parameter("m_u").unwrap()])
        * v[system.parameter("g").unwrap()];
    let s = id as f64;
    let travel = if id == 2 { 0.09 } else { 0.02 };
    vec![
        (
            "z_s_a".into(),
            (0..n).map(|k| wave(k, 1.2, 1.5 + 0.1 * s, s)).collect(),
        ),
        (
            "d_suspension".into(),
            (0..n).map(|k| wave(k, 1.7, travel, 0.2 * s)).collect(),
        ),
        (
            "f_tyre".into(),
            (0..n)
                .map(|k| static_load + wave(k, 10.0, 400.0 + 10.0 * s, s))
                .collect(),
        ),
    ]
}

/// The bridge's index channels: mid-span deflection and acceleration, suspension force.
fn bridge_columns(id: i64, n: usize) -> Columns {
    let s = id as f64;
    vec![
        (
            "z_mid".into(),
            (0..n)
                .map(|k| 1.0e-3 * (k as f64 / n as f64) + wave(k, 4.0, 1e-4, s))
                .collect(),
        ),
        (
            "z_mid_a".into(),
            (0..n)
                .map(|k| wave(k, 4.0, 1.0 + s, s) + if id == 1 && k == 700 { 10.0 } else { 0.0 })
                .collect(),
        ),
        (
            "f_suspension".into(),
            (0..n).map(|k| 56e3 + wave(k, 2.0, 5e3, s)).collect(),
        ),
    ]
}

/// Writes a simulation file of `system`'s samples `ids` (`n` rows each, `t` from 0 every `DT`).
fn write_sim(path: &Path, system: &System, ids: &[i64], n: usize, signals: Signals, edit: Edit) {
    let mut t = Table::default().with_units(pino_data::system::units_of(system).unwrap());
    let mut sid = Vec::new();
    let mut time = Vec::new();
    let mut cols: Columns = Vec::new();
    for &id in ids {
        let mut c = signals(id, n);
        edit(id, &mut c);
        let rows = c.first().map_or(n, |c| c.1.len());
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
        cols = signals(0, 0);
    }
    t.push(schema::SAMPLE_ID, Column::I64(sid)).unwrap();
    t.push(schema::TIME, Column::F64(time)).unwrap();
    for (name, v) in cols {
        t.push(&name, Column::F64(v)).unwrap();
    }
    pino_data::write_parquet(path, &t).unwrap();
}

fn write_params(path: &Path, system: &System, ids: &[i64]) {
    let mut t = Table::default().with_units(pino_data::system::units_of(system).unwrap());
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
    for (j, name) in system.sampled_names().into_iter().enumerate() {
        t.push(
            name,
            Column::F64(
                ids.iter()
                    .map(|&i| params_of(system, i).as_slice()[j])
                    .collect(),
            ),
        )
        .unwrap();
    }
    pino_data::write_parquet(path, &t).unwrap();
}

struct Fixture {
    dir: tempfile::TempDir,
    system: System,
    params: BTreeMap<i64, SampleInfo>,
    files: Vec<PathBuf>,
}

impl Fixture {
    fn compute(&self, cfg: &IndexConfig) -> Result<Computed> {
        compute_all(&self.system, &self.params, &self.files, cfg, &|_| {})
    }
}

/// Samples 0-5 in `params.parquet`; 0-2 simulated in `a.parquet`, 3-4 in `b.parquet` (`n`
/// rows each), 5 absent (a failed simulation).
fn fixture(system: System, n: usize, signals: Signals, edit: Edit) -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let params_file = dir.path().join("params.parquet");
    write_params(&params_file, &system, &[0, 1, 2, 3, 4, 5]);
    let files = vec![dir.path().join("a.parquet"), dir.path().join("b.parquet")];
    write_sim(&files[0], &system, &[0, 1, 2], n, signals, edit);
    write_sim(&files[1], &system, &[3, 4], n, signals, edit);
    let params = read_params(&system, std::slice::from_ref(&params_file)).unwrap();
    Fixture {
        dir,
        system,
        params,
        files,
    }
}

fn vtcd(edit: Edit) -> Fixture {
    fixture(compile("vtcd.yaml", VTCD), 1500, &railway_columns, edit)
}

/// [`vtcd`] read from t = 0 (`indices_from: 0`), for the tests of what the whole record holds.
fn vtcd_from_start(edit: Edit) -> Fixture {
    let mut system = compile("vtcd.yaml", VTCD);
    system.indices_from = 0.0;
    fixture(system, 1500, &railway_columns, edit)
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
    let fx = vtcd(&|_, _| {});
    // The vehicle-track description samples the 14 parameters of the public schema, in order.
    assert_eq!(fx.system.sampled_names(), vehicle_track::PARAMETERS);
    let got = fx.compute(&cfg(0.1)).unwrap();
    // The stage reads from the later of the fraction's row 150 and the description's
    // `indices_from` (0.2 s: row 200).
    let c = cfg(0.1).of_system(&fx.system);
    assert_eq!(fx.system.indices_from, 0.2);
    assert!(got.railway);
    assert_eq!(got.rows.len(), 5);
    assert_eq!(got.absent, 1);
    assert_eq!(
        got.rows.iter().map(|r| r.id).collect::<Vec<_>>(),
        vec![0, 1, 2, 3, 4]
    );
    let railway = IndexSet::of(&fx.system).railway.unwrap();
    for row in &got.rows {
        let cols = railway_columns(row.id, 1500);
        let s = |name: &String| cols.iter().find(|(n, _)| n == name).unwrap().1.as_slice();
        let rec = Record {
            dt: DT,
            p: railway.p.each_ref().map(s),
            z_c_a: s(&railway.z_c_a),
            beta_c_a: s(&railway.beta_c_a),
            z_t_a: railway.z_t_a.each_ref().map(s),
            z_r: railway.z_r.each_ref().map(s),
        };
        let times: Vec<f64> = (0..1500).map(|k| k as f64 * DT).collect();
        let first = c.first_row(&times);
        assert_eq!(first, 200);
        let win = rec.tail(first);
        let p = params_of(&fx.system, row.id);
        let value = |name: &str| p.get(name).unwrap();
        let l_c = value("l_c");
        // The binding's W is the hand-written vehicle's, bit for bit (the outputs of the
        // vehicle-track pipeline stay as they were).
        let w = vehicle_track::HalfVehicle::new(value, 9.81).w;
        let binding = fx.system.railway.as_ref().unwrap();
        let values = fx.system.values(&p).unwrap();
        assert_eq!(
            binding.static_wheel_load.eval(&values).to_bits(),
            w.to_bits()
        );
        assert_eq!(binding.half_length.eval(&values).to_bits(), l_c.to_bits());
        // The polars extremes are the plain fold's, exactly.
        let plain = Aggregates::fold(&win, l_c).unwrap();
        let windows = [(row.id, first as f64 * DT)];
        let ext = aggregate(&fx.files, &railway, &windows, &|_| PathBuf::new()).unwrap()[&row.id];
        assert_eq!(ext.n, plain.n);
        assert_eq!(ext.p_max, plain.p_max);
        assert_eq!(ext.p_min, plain.p_min);
        assert_eq!(ext.bogie_abs_max, plain.bogie_abs_max);
        assert_eq!(ext.z_r_max, plain.z_r_max);
        // And the indices of the stage's path against `pino_indices::compute`: same
        // arithmetic in the same order, the same bits.
        let want = pino_indices::compute(&win, l_c, w, &c).unwrap();
        assert_eq!(row.railway, Some(want));
        assert_eq!(row.values, want.values());
        assert_eq!(row.window_s, want.window_s);
        assert_eq!(row.failed, c.limits.failed(&want));
        // The spike of p_1 at row 37 is before the window; p_2's at 74 too; p_4's at 148.
        assert!(want.peak_wheel_rail_force_kn < 70.0 + 25.0);
    }
    // Deterministic bytes, and the table's layout.
    write_outputs(fx.dir.path(), &fx.system, &got, &c).unwrap();
    let a = std::fs::read(fx.dir.path().join("indices.parquet")).unwrap();
    write_outputs(fx.dir.path(), &fx.system, &got, &c).unwrap();
    assert_eq!(
        a,
        std::fs::read(fx.dir.path().join("indices.parquet")).unwrap()
    );
    let t = pino_data::read_parquet(&fx.dir.path().join("indices.parquet"), None).unwrap();
    let names: Vec<&str> = t.names().collect();
    assert_eq!(names.len(), 2 + 14 + 14 + 3);
    assert_eq!(names[2..16], vehicle_track::PARAMETERS);
    let index_names: Vec<&str> = pino_indices::INDEX_COLUMNS.iter().map(|c| c.name).collect();
    assert_eq!(names[16..30], index_names);
    assert_eq!(names[30..], ["window_s", "pass", "failed"]);
    assert_eq!(t.str("split").unwrap()[3], "test");
    let json = std::fs::read_to_string(fx.dir.path().join("indices.json")).unwrap();
    assert!(
        json.contains("\"sperling.segment_s\": \"whole window\"")
            && json.contains("\"system\": \"vehicle-track\"")
            && !json.contains("gravity"),
        "{json}"
    );
    let line = summary(&got);
    assert!(
        line.starts_with("indices of 5 samples (1 absent from the dataset)")
            && line.contains("worst: peak force"),
        "{line}"
    );
}

/// The hand computation of `stat(x - subtract) / divide` for each statistic.
#[test]
fn simple_indices_equal_a_hand_computation_for_each_stat() {
    let text = with_indices(
        QUARTER_CAR,
        "indices:
  travel_max: {stat: max, channel: d_suspension, subtract: 0.5, divide: 2, unit: m, limit: 2.0}
  travel_min: {stat: min, channel: d_suspension, subtract: 0.5, divide: 2, unit: m}
  travel_max_abs: {stat: max_abs, channel: d_suspension, subtract: 0.5, divide: 2, unit: m, limit: 2.2}
  travel_rms: {stat: rms, channel: d_suspension, subtract: 0.5, divide: 2, unit: m}
  travel_peak_to_peak: {stat: peak_to_peak, channel: d_suspension, subtract: 0.5, divide: 2, unit: m}
  travel_over_static: {stat: max, channel: d_suspension, divide: m_s * g, unit: m/N}
",
    );
    let system = compile("every-stat.yaml", &text);
    // 8 rows, window from row floor(0.25 * 8) = 2: the +-100 before it must not count.
    // x - 0.5 over the window = [1, -5, 4, 0, -1, 2].
    let x = [100.0, -100.0, 1.5, -4.5, 4.5, 0.5, -0.5, 2.5];
    let signals =
        |_: i64, n: usize| -> Columns { vec![("d_suspension".into(), x[..n.min(8)].to_vec())] };
    let fx = fixture(system, 8, &signals, &|_, _| {});
    let got = fx.compute(&cfg(0.25)).unwrap();
    assert!(!got.railway);
    let names: Vec<&str> = got.columns.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "travel_max",
            "travel_min",
            "travel_max_abs",
            "travel_rms",
            "travel_peak_to_peak",
            "travel_over_static"
        ]
    );
    for row in &got.rows {
        // m_s of this sample times g.
        let weight = params_of(&fx.system, row.id).get("m_s").unwrap() * 9.81;
        let want = [
            4.0 / 2.0,
            -5.0 / 2.0,
            5.0 / 2.0,
            ((1.0 + 25.0 + 16.0 + 0.0 + 1.0 + 4.0) / 6.0f64).sqrt() / 2.0,
            9.0 / 2.0,
            4.5 / weight,
        ];
        for (k, (g, w)) in row.values.iter().zip(want).enumerate() {
            assert!((g - w).abs() <= 1e-15 * w.abs(), "{}: {g} vs {w}", names[k]);
        }
        assert_eq!(row.window_s, 6.0 * DT);
        // travel_max is at its limit (passes); travel_max_abs exceeds its own.
        assert_eq!(row.failed, ["travel_max_abs"]);
    }
}

#[test]
fn a_description_without_railway_binding_gets_its_simple_indices() {
    // The quarter car: RMS body acceleration, suspension travel (limit 8 cm), dynamic tyre
    // load (RMS about the static load over the static load).
    let system = compile("quarter-car.yaml", QUARTER_CAR);
    assert!(system.railway.is_none());
    let fx = fixture(system, 1000, &quarter_car_columns, &|_, _| {});
    let c = cfg(0.1);
    let got = fx.compute(&c).unwrap();
    assert_eq!((got.rows.len(), got.absent), (5, 1));
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    for row in &got.rows {
        let cols = quarter_car_columns(row.id, 1000);
        let win = |k: usize| &cols[k].1[100..];
        let p = params_of(&fx.system, row.id);
        let mass = |name: &str| p.get(name).unwrap();
        let static_load = (mass("m_s") + mass("m_u")) * 9.81;
        let dyn_load: Vec<f64> = win(2).iter().map(|f| f - static_load).collect();
        let want = [
            rms(win(0)),
            win(1).iter().fold(0.0f64, |m, v| m.max(v.abs())),
            rms(&dyn_load) / static_load,
        ];
        for (g, w) in row.values.iter().zip(want) {
            assert!(
                (g - w).abs() <= 1e-12 * w.abs(),
                "sample {}: {g} vs {w}",
                row.id
            );
        }
        // The tyre force's sinusoid about the static load, 9 whole periods in the window: its
        // RMS is the amplitude (400 + 10 id N) over sqrt 2.
        let amplitude = 400.0 + 10.0 * row.id as f64;
        assert!((want[2] * static_load - amplitude / 2f64.sqrt()).abs() < 1e-9 * amplitude);
        let over = if row.id == 2 {
            vec!["suspension_travel"]
        } else {
            vec![]
        };
        assert_eq!(row.failed, over, "sample {}", row.id);
        assert_eq!(row.railway, None);
        assert_eq!(row.window_s, 900.0 * DT);
    }
    write_outputs(fx.dir.path(), &fx.system, &got, &c).unwrap();
    let path = fx.dir.path().join("indices.parquet");
    let t = pino_data::read_parquet(&path, None).unwrap();
    let names: Vec<&str> = t.names().collect();
    assert_eq!(
        names,
        [
            "sample_id",
            "split",
            "m_s",
            "m_u",
            "k_s",
            "c_s",
            "k_t",
            "v_kmh",
            "sprung_rms_acceleration",
            "suspension_travel",
            "dynamic_tyre_load",
            "window_s",
            "pass",
            "failed"
        ]
    );
    assert_eq!(t.bool("pass").unwrap(), [true, true, false, true, true]);
    assert_eq!(
        t.opt_str("failed").unwrap(),
        [None, None, Some("suspension_travel"), None, None]
    );
    // Units from the description: the stated ones, a ratio's `1`.
    let units = pino_data::metadata::read_metadata(&path)
        .unwrap()
        .column_units;
    let unit = |c: &str| {
        units
            .iter()
            .find(|(n, _)| n == c)
            .unwrap()
            .1
            .clone()
            .unwrap()
    };
    assert_eq!(unit("sprung_rms_acceleration"), "m/s^2");
    assert_eq!(unit("suspension_travel"), "m");
    assert_eq!(unit("dynamic_tyre_load"), "1");
    assert_eq!(unit("m_s"), "kg");
    let json = std::fs::read_to_string(fx.dir.path().join("indices.json")).unwrap();
    assert!(
        json.contains("\"system\": \"quarter-car\"")
            && json.contains("\"limit\": 0.08")
            && json.contains("rms of (f_tyre - "),
        "{json}"
    );
    let line = summary(&got);
    assert!(
        line.contains("1 exceed a limit")
            && line.contains("worst: sprung_rms_acceleration ")
            && line.contains(" m/s^2, suspension_travel 0.0")
            && line.contains(" m, dynamic_tyre_load "),
        "{line}"
    );

    // The bridge: dynamic amplification over the static deflection (a derived parameter),
    // peak deck acceleration (limit 3.5 m/s^2), peak force over the weight.
    let fx = fixture(
        compile("bridge.yaml", BRIDGE),
        1000,
        &bridge_columns,
        &|_, _| {},
    );
    let got = fx.compute(&cfg(0.0)).unwrap();
    for row in &got.rows {
        let cols = bridge_columns(row.id, 1000);
        let p = params_of(&fx.system, row.id);
        let (m_v, g, span, ei) = (p.get("m_v").unwrap(), 9.81, 25.0f64, 8.323e9);
        let max = |x: &[f64]| x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let want = [
            max(&cols[0].1) / (m_v * g * span.powi(3) / (48.0 * ei)),
            cols[1].1.iter().fold(0.0f64, |m, v| m.max(v.abs())),
            max(&cols[2].1) / (m_v * g),
        ];
        for (g, w) in row.values.iter().zip(want) {
            assert!(
                (g - w).abs() <= 1e-12 * w.abs(),
                "sample {}: {g} vs {w}",
                row.id
            );
        }
        // Amplitudes 1 + id m/s^2, and a spike of 10 in sample 1.
        let over = if row.id == 1 || row.id >= 3 {
            vec!["peak_deck_acceleration"]
        } else {
            vec![]
        };
        assert_eq!(row.failed, over, "sample {}", row.id);
    }
    assert!(
        summary(&got).contains("worst: dynamic_amplification "),
        "{}",
        summary(&got)
    );
}

#[test]
fn a_description_without_indices_writes_the_keys() {
    let system = compile("no-index.yaml", &with_indices(QUARTER_CAR, ""));
    assert!(system.indices.is_empty() && system.railway.is_none());
    // Only `sample_id` and `t` are read (the keys and the window's length).
    let fx = fixture(
        system,
        100,
        &|_, n| vec![("z_s".into(), vec![0.0; n])],
        &|_, _| {},
    );
    let c = cfg(0.0);
    let got = fx.compute(&c).unwrap();
    assert_eq!((got.rows.len(), got.absent), (5, 1));
    assert!(got
        .rows
        .iter()
        .all(|r| r.values.is_empty() && r.failed.is_empty()));
    write_outputs(fx.dir.path(), &fx.system, &got, &c).unwrap();
    let t = pino_data::read_parquet(&fx.dir.path().join("indices.parquet"), None).unwrap();
    assert_eq!(t.names().count(), 2 + 6 + 3);
    assert_eq!(t.f64("window_s").unwrap(), [100.0 * DT; 5]);
    let line = summary(&got);
    assert!(
        line.contains("`quarter-car` declares no index") && line.contains("keys only"),
        "{line}"
    );
}

#[test]
fn a_missing_column_names_file_and_column() {
    let fx = vtcd(&|_, _| {});
    write_sim(
        &fx.files[1],
        &fx.system,
        &[3, 4],
        100,
        &railway_columns,
        &|_, c| c.retain(|(n, _)| n != "p_3"),
    );
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(
        e.contains("b.parquet") && e.contains("missing column `p_3`"),
        "{e}"
    );
    // A simple index's channel.
    let fx = fixture(
        compile("quarter-car.yaml", QUARTER_CAR),
        100,
        &quarter_car_columns,
        &|_, c| c.retain(|(n, _)| n != "f_tyre"),
    );
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(
        e.contains("a.parquet") && e.contains("missing column `f_tyre`"),
        "{e}"
    );
}

#[test]
fn nan_names_file_sample_and_column() {
    // In a signal of the polars pass (the row counted from the window's first, row 150) ...
    let fx = vtcd_from_start(&|id, c| {
        if id == 4 {
            c.iter_mut().find(|(n, _)| n == "z_r2").unwrap().1[900] = f64::NAN;
        }
    });
    let e = fx.compute(&cfg(0.1)).unwrap_err().to_string();
    assert!(
        e.contains("b.parquet")
            && e.contains("sample 4")
            && e.contains("`z_r2`")
            && e.contains("row 750 of the window")
            && e.contains("NaN"),
        "{e}"
    );
    // ... in one of the record pass (with the row) ...
    let fx = vtcd_from_start(&|id, c| {
        if id == 1 {
            c.iter_mut().find(|(n, _)| n == "beta_c_a").unwrap().1[10] = f64::INFINITY;
        }
    });
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(
        e.contains("a.parquet")
            && e.contains("sample 1")
            && e.contains("`beta_c_a`")
            && e.contains("row 10"),
        "{e}"
    );
    // ... and in the channel of a simple index.
    let fx = fixture(
        compile("quarter-car.yaml", QUARTER_CAR),
        1000,
        &quarter_car_columns,
        &|id, c| {
            if id == 3 {
                c.iter_mut().find(|(n, _)| n == "z_s_a").unwrap().1[600] = f64::NAN;
            }
        },
    );
    let e = fx.compute(&cfg(0.1)).unwrap_err().to_string();
    assert!(
        e.contains("b.parquet")
            && e.contains("sample 3")
            && e.contains("`z_s_a`")
            && e.contains("row 500 of the window")
            && e.contains("NaN"),
        "{e}"
    );
    // Before the window a NaN does not matter.
    let fx = vtcd_from_start(&|id, c| {
        if id == 1 {
            c.iter_mut().find(|(n, _)| n == "p_1").unwrap().1[10] = f64::NAN;
        }
    });
    fx.compute(&cfg(0.1)).unwrap();
}

#[test]
fn empty_and_inconsistent_samples_are_refused() {
    // A sample of one row.
    let fx = vtcd_from_start(&|_, _| {});
    write_sim(
        &fx.files[1],
        &fx.system,
        &[3, 4],
        1500,
        &railway_columns,
        &|id, c| {
            if id == 3 {
                for (_, v) in c.iter_mut() {
                    v.truncate(1);
                }
            }
        },
    );
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(
        e.contains("b.parquet") && e.contains("sample 3") && e.contains("1 points"),
        "{e}"
    );
    // Files without a single row.
    let fx = vtcd_from_start(&|_, _| {});
    for f in &fx.files {
        write_sim(f, &fx.system, &[], 10, &railway_columns, &|_, _| {});
    }
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(e.contains("no simulated sample"), "{e}");
    // A sample in two files; a sample twice in one file; a sample unknown to params.parquet.
    let fx = vtcd_from_start(&|_, _| {});
    write_sim(
        &fx.files[1],
        &fx.system,
        &[2, 3],
        200,
        &railway_columns,
        &|_, _| {},
    );
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(
        e.contains("b.parquet") && e.contains("sample 2 is also in") && e.contains("a.parquet"),
        "{e}"
    );
    write_sim(
        &fx.files[1],
        &fx.system,
        &[3, 4, 3],
        200,
        &railway_columns,
        &|_, _| {},
    );
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(
        e.contains("b.parquet") && e.contains("rows of sample 3 are not contiguous"),
        "{e}"
    );
    write_sim(
        &fx.files[1],
        &fx.system,
        &[3, 9],
        200,
        &railway_columns,
        &|_, _| {},
    );
    let e = fx.compute(&cfg(0.0)).unwrap_err().to_string();
    assert!(e.contains("sample 9 is not in params.parquet"), "{e}");
}
