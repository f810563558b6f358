//! The indices of a described system ([`pino_indices::IndexSet`]) on the repository's three
//! descriptions: which columns each defines and reads, the simple statistics against hand
//! computations, the railway family through the binding equal to [`pino_indices::compute`]
//! with the hand-written vehicle's `W` and `l_c` (the same bits), and the limits.

use mbd_system::schema::IndexStat;
use mbd_system::system::ParamSource;
use mbd_system::{System, SystemSource};
use pino_indices::system::simple;
use pino_indices::{
    lateral_indices, IndexParams, IndexSet, LateralParams, LateralRecord, Record, INDEX_COLUMNS,
    LATERAL_COLUMNS,
};

fn compile(file: &str, text: &str) -> System {
    SystemSource {
        file: file.into(),
        text: text.into(),
        values: Default::default(),
    }
    .compile()
    .unwrap_or_else(|e| panic!("{file}: {e}"))
}

fn vtcd() -> System {
    compile("vtcd.yaml", include_str!("../../../systems/vtcd.yaml"))
}

fn quarter_car() -> System {
    compile(
        "quarter-car.yaml",
        include_str!("../../../systems/quarter-car.yaml"),
    )
}

fn bridge() -> System {
    compile("bridge.yaml", include_str!("../../../systems/bridge.yaml"))
}

fn nominal(system: &System) -> mbd_system::Sampled {
    let values: Vec<f64> = system
        .sampled()
        .into_iter()
        .map(|i| match system.parameters[i].source {
            ParamSource::Sampled { nominal, .. } => nominal,
            _ => unreachable!("sampled"),
        })
        .collect();
    system.sampled_values(values).unwrap()
}

#[test]
fn each_statistic_is_its_hand_computation() {
    // x - 1 = [2, -4, 3, 0, 1]; divided by 4.
    let x = [3.0, -3.0, 4.0, 1.0, 2.0];
    let cases = [
        (IndexStat::Max, 3.0 / 4.0),
        (IndexStat::Min, -4.0 / 4.0),
        (IndexStat::MaxAbs, 4.0 / 4.0),
        (
            IndexStat::Rms,
            ((4.0 + 16.0 + 9.0 + 0.0 + 1.0) / 5.0f64).sqrt() / 4.0,
        ),
        (IndexStat::PeakToPeak, 7.0 / 4.0),
    ];
    for (stat, want) in cases {
        assert_eq!(simple(stat, &x, 1.0, 4.0), want, "{}", stat.keyword());
    }
    // Every statistic is covered.
    assert_eq!(cases.len(), IndexStat::ALL.len());
    // Without subtract and divide, max |x| is the largest magnitude of either sign.
    assert_eq!(simple(IndexStat::MaxAbs, &x, 0.0, 1.0), 4.0);
    assert_eq!(simple(IndexStat::Min, &x, 0.0, 1.0), -3.0);
}

#[test]
fn each_description_defines_its_columns_and_inputs() {
    let system = vtcd();
    let set = IndexSet::of(&system);
    let r = set
        .railway
        .as_ref()
        .expect("vtcd.yaml binds the railway indices");
    assert_eq!(r.p, ["p_1", "p_2", "p_3", "p_4"]);
    assert_eq!(
        (r.z_c_a.as_str(), r.beta_c_a.as_str()),
        ("z_c_a", "beta_c_a")
    );
    assert_eq!(r.z_t_a, ["z_t1_a", "z_t2_a"]);
    assert_eq!(r.z_r, ["z_r1", "z_r2", "z_r3", "z_r4"]);
    let names: Vec<String> = set.columns(&system).into_iter().map(|c| c.name).collect();
    let railway: Vec<&str> = INDEX_COLUMNS.iter().map(|c| c.name).collect();
    assert_eq!(names, railway);
    assert_eq!(set.inputs().len(), 12);

    let system = quarter_car();
    let set = IndexSet::of(&system);
    assert!(set.railway.is_none() && !set.is_empty());
    let cols = set.columns(&system);
    let got: Vec<(&str, &str)> = cols
        .iter()
        .map(|c| (c.name.as_str(), c.unit.as_str()))
        .collect();
    assert_eq!(
        got,
        [
            ("sprung_rms_acceleration", "m/s^2"),
            ("suspension_travel", "m"),
            ("dynamic_tyre_load", "1"),
        ]
    );
    assert!(
        cols[2].definition.starts_with("rms of (f_tyre - "),
        "{}",
        cols[2].definition
    );
    assert_eq!(set.inputs(), ["z_s_a", "d_suspension", "f_tyre"]);

    let system = bridge();
    let names: Vec<String> = IndexSet::of(&system)
        .columns(&system)
        .into_iter()
        .map(|c| c.name)
        .collect();
    assert_eq!(
        names,
        [
            "dynamic_amplification",
            "peak_deck_acceleration",
            "peak_contact_force"
        ]
    );
}

#[test]
fn the_railway_family_through_the_binding_is_compute_with_the_vehicle_w() {
    let system = vtcd();
    let set = IndexSet::of(&system);
    let sampled = nominal(&system);
    let values = system.values(&sampled).unwrap();
    let n = 1000;
    let dt = 1e-3;
    let sig = |f: f64, a: f64, c: f64| -> Vec<f64> {
        (0..n)
            .map(|k| c + a * (2.0 * std::f64::consts::PI * f * k as f64 * dt).sin())
            .collect()
    };
    let p = sig(20.0, 9e3, 62e3);
    let z = sig(3.0, 0.1, 0.0);
    let b = sig(2.0, 0.005, 0.0);
    let t = sig(7.0, 1.5, 0.0);
    let r = sig(30.0, 2e-4, 9e-4);
    let get = |c: &str| -> Option<Vec<f64>> {
        Some(match c {
            "p_1" | "p_2" | "p_3" | "p_4" => p.clone(),
            "z_c_a" => z.clone(),
            "beta_c_a" => b.clone(),
            "z_t1_a" | "z_t2_a" => t.clone(),
            "z_r1" | "z_r2" | "z_r3" | "z_r4" => r.clone(),
            _ => return None,
        })
    };
    let cfg = IndexParams::default().validate().unwrap();
    let (got, railway) = set.compute(&system, &values, &get, dt, &cfg).unwrap();
    // The static wheel load of the half vehicle as the hand-written vehicle computes it
    // (`mbd_test_models::vehicle_track::HalfVehicle`, g = 9.81), and l_c.
    let v = |name: &str| values[system.parameter(name).unwrap()];
    let (m_c, m_t, m_w) = (v("m_c") / 2.0, v("m_t") / 2.0, v("m_w") / 2.0);
    let w = (m_c + 2.0 * m_t + 4.0 * m_w) * 9.81 / 4.0;
    let rec = Record {
        dt,
        p: [&p, &p, &p, &p],
        z_c_a: &z,
        beta_c_a: &b,
        z_t_a: [&t, &t],
        z_r: [&r, &r, &r, &r],
    };
    let want = pino_indices::compute(&rec, v("l_c"), w, &cfg).unwrap();
    assert_eq!(railway, Some(want));
    assert_eq!(got, want.values());
    // 62 - 9 kN under a W of about 62.6 kN: every wheel unloads by about 15 %.
    assert!(
        (0.1..0.2).contains(&want.wheel_load_reduction_rate),
        "{}",
        want.wheel_load_reduction_rate
    );
    // Gentle car-body accelerations (W_z about 1.8): every limit holds.
    assert!(set.failed(&system, &got, railway.as_ref(), &cfg).is_empty());
    // A column the binding names but the caller lacks is named.
    let e = set
        .compute(
            &system,
            &values,
            &|c| if c == "z_r3" { None } else { get(c) },
            dt,
            &cfg,
        )
        .unwrap_err();
    assert!(e.to_string().contains("`z_r3`"), "{e}");
}

#[test]
fn simple_indices_over_a_record_and_their_limits() {
    let system = quarter_car();
    let set = IndexSet::of(&system);
    let values = system.values(&nominal(&system)).unwrap();
    let static_load = (320.0 + 40.0) * 9.81;
    let z_s_a = [0.5, -1.5, 1.0, -0.5];
    let travel = [0.01, -0.09, 0.03, 0.0];
    let f_tyre: Vec<f64> = [100.0, -300.0, 200.0, 0.0]
        .iter()
        .map(|d| static_load + d)
        .collect();
    let get = |c: &str| -> Option<Vec<f64>> {
        match c {
            "z_s_a" => Some(z_s_a.to_vec()),
            "d_suspension" => Some(travel.to_vec()),
            "f_tyre" => Some(f_tyre.clone()),
            _ => None,
        }
    };
    let cfg = IndexParams::default().validate().unwrap();
    let (got, railway) = set.compute(&system, &values, &get, 1e-3, &cfg).unwrap();
    assert!(railway.is_none());
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    let want = [
        rms(&z_s_a),
        0.09,
        rms(&[100.0, -300.0, 200.0, 0.0]) / static_load,
    ];
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() <= 1e-12 * w, "{g} vs {w}");
    }
    // 9 cm of travel exceeds the description's 8 cm limit.
    assert_eq!(set.failed(&system, &got, None, &cfg), ["suspension_travel"]);
    // A NaN in a channel is named with its row.
    let e = set
        .compute(
            &system,
            &values,
            &|c| {
                let mut v = get(c)?;
                if c == "f_tyre" {
                    v[2] = f64::NAN;
                }
                Some(v)
            },
            1e-3,
            &cfg,
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("`f_tyre`") && e.contains("row 2"), "{e}");
}

fn vtcd_3d() -> System {
    compile(
        "vtcd-3d.yaml",
        include_str!("../../../systems/vtcd-3d.yaml"),
    )
}

/// The spatial vehicle binds both families: the railway columns, then the lateral ones; through
/// the binding the lateral values are [`pino_indices::lateral_indices`] with the sample's speed,
/// `l_c`, floor height and axle load `2 W`; the description's limits judge them (a steady
/// `Y/Q` of 0.9 fails the 0.8 of the 2 m mean, its 65 kN track shift force the Prud'homme
/// limit of about 52 kN, a gentle sway passes `W_y` 2.5 and a decay the stability limit).
#[test]
fn the_lateral_family_through_the_binding() {
    let system = vtcd_3d();
    let set = IndexSet::of(&system);
    let l = set
        .lateral
        .as_ref()
        .expect("vtcd-3d.yaml binds the lateral indices");
    assert_eq!(l.wheels[0], ["fy_ws1_l".to_owned(), "p_ws1_l".to_owned()]);
    assert_eq!(l.wheels.len(), 8);
    let names: Vec<String> = set.columns(&system).into_iter().map(|c| c.name).collect();
    let want: Vec<&str> = INDEX_COLUMNS
        .iter()
        .chain(&LATERAL_COLUMNS)
        .map(|c| c.name)
        .collect();
    assert_eq!(names, want);
    let sampled = nominal(&system);
    let values = system.values(&sampled).unwrap();
    let (n, dt) = (3000, 1e-3);
    let wave = |f: f64, a: f64, c: f64| -> Vec<f64> {
        (0..n)
            .map(|k| c + a * (2.0 * std::f64::consts::PI * f * k as f64 * dt).sin())
            .collect()
    };
    // Wheels under 70 kN, the right one of the leading wheelset pushed to Y/Q 0.9; the car
    // body swaying gently; the leading wheelset's shift decaying after the excitations end.
    let q = vec![7.0e4; n];
    let y_hi = vec![0.9 * 7.0e4; n];
    let y_lo = vec![-2.0e3; n];
    let car = wave(1.0, 0.2, 0.0);
    let shift: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            1e-3 * (-t).exp() * (2.0 * std::f64::consts::PI * 4.0 * t).sin()
        })
        .collect();
    let excitation: Vec<f64> = (0..n).map(|k| if k < 1000 { 1e-4 } else { 0.0 }).collect();
    let get = |c: &str| -> Option<Vec<f64>> {
        Some(match c {
            "fy_ws1_r" => y_hi.clone(),
            c if c.starts_with("fy_ws") => y_lo.clone(),
            c if c.starts_with("p_ws") => q.clone(),
            c if c.starts_with("eta_") => excitation.clone(),
            "y_w1" => shift.clone(),
            "y_c_a" => car.clone(),
            "psi_c_a" | "phi_c_a" => vec![0.0; n],
            "z_c_a" | "beta_c_a" | "z_t1_a" | "z_t2_a" => vec![0.0; n],
            c if c.starts_with("z_r") => vec![0.0; n],
            _ => return None,
        })
    };
    let cfg = IndexParams::default().validate().unwrap();
    let (got, railway) = set.compute(&system, &values, &get, dt, &cfg).unwrap();
    let lat = &got[INDEX_COLUMNS.len()..];
    let v = |name: &str| values[system.parameter(name).unwrap()];
    let p = LateralParams {
        speed: v("v_kmh") / 3.6,
        half_length: v("l_c"),
        floor: v("h_floor"),
        axle_load: 2.0 * v("W"),
        prudhomme: 1.0,
    };
    let wheels: Vec<(&[f64], &[f64])> = (0..8)
        .map(|k| (if k == 1 { &y_hi[..] } else { &y_lo[..] }, &q[..]))
        .collect();
    let zero = vec![0.0; n];
    let rec = LateralRecord {
        dt,
        wheels,
        car_body: [&car, &zero, &zero],
        stability: &shift,
        excitations: vec![&excitation; l.excitations.len()],
    };
    let direct = lateral_indices(&rec, &p, &cfg.sperling).unwrap();
    assert_eq!(lat, direct);
    assert!((lat[1] - 0.9).abs() < 1e-12, "{}", lat[1]);
    // The decay rate of exp(-t): about -1 /s.
    assert!((lat[13] + 1.0).abs() < 0.05, "{}", lat[13]);
    let failed = set.failed(&system, &got, railway.as_ref(), &cfg);
    assert_eq!(
        failed,
        ["derailment_quotient_2m", "prudhomme_ratio"],
        "{:?}",
        &lat
    );
    let limits = set.column_limits(&system, &cfg);
    let k = INDEX_COLUMNS.len();
    assert_eq!(limits[k + 1], Some(0.8));
    assert_eq!(limits[k + 13], Some(0.0));
}
