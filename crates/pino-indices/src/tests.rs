//! Known answers: the Sperling closed form of a sinusoid, the wheel load reduction rate and
//! the peaks of hand-made histories, and the failure modes of bad input.

use super::*;
use crate::sperling::{sperling_wz, weighting};

const DT: f64 = 1e-3;

fn sine(n: usize, amp: f64, f: f64) -> Vec<f64> {
    (0..n)
        .map(|k| amp * (2.0 * std::f64::consts::PI * f * k as f64 * DT).sin())
        .collect()
}

/// `0.896 (a^3 F(f) / f)^0.1`, `a` in cm/s^2.
fn closed_form(a_cm: f64, f: f64) -> f64 {
    0.896 * (a_cm.powi(3) * weighting(f) / f).powf(0.1)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn sperling_of_a_sinusoid_is_the_closed_form_in_every_band() {
    // 2 s at 1 kHz: lines every 0.5 Hz. One frequency in each branch of F(f).
    let p = SperlingParams::default();
    for (amp, f) in [(0.3, 3.0), (0.5, 10.0), (0.2, 25.0), (1.0, 0.5)] {
        let a = sine(2000, amp, f);
        let wz = sperling_wz(&a, DT, &p).unwrap();
        let want = closed_form(100.0 * amp, f);
        assert!(rel(wz, want) < 1e-10, "f = {f}: {wz} vs {want}");
    }
    // The weighting is the definition's, continuous nowhere but where it says.
    assert!((weighting(5.9) - 400.0 / 5.9f64.powi(2)).abs() < 1e-12);
    assert_eq!(weighting(20.0), 1.0);
    // Below f_min nothing counts: a 0.25 Hz sinusoid over 4 s leaves only FFT round-off on the
    // other lines (W_z ~ 1e-4: the 1/10 power lifts a sum of 1e-40 that far).
    let slow = sine(4000, 1.0, 0.25);
    let wz = sperling_wz(&slow, DT, &p).unwrap();
    assert!(wz < 1e-3 && wz < 1e-3 * closed_form(100.0, 0.5), "{wz}");
}

#[test]
fn sperling_with_a_hann_taper_spreads_a_line_over_its_neighbours() {
    // A periodic Hann window turns one line of amplitude A into A at f and A/2 at f -/+ df
    // (coherent-gain normalisation): W_z^10 / 0.896^10 = sum of the three terms.
    let p = SperlingParams {
        taper: Taper::Hann,
        ..SperlingParams::default()
    };
    let (amp, f, df) = (0.4, 8.0, 0.5);
    let wz = sperling_wz(&sine(2000, amp, f), DT, &p).unwrap();
    let a = 100.0 * amp;
    let term = |a: f64, f: f64| a.powi(3) * weighting(f) / f;
    let want = 0.896 * (term(a, f) + term(a / 2.0, f - df) + term(a / 2.0, f + df)).powf(0.1);
    assert!(rel(wz, want) < 1e-10, "{wz} vs {want}");
}

#[test]
fn sperling_segments_report_the_worst_section() {
    // 4 s: a quiet first half and a 6 Hz sinusoid in the second. Whole window: the line at
    // 6 Hz has amplitude A/2 plus leakage; with 2-s segments the index is the loud half's
    // closed form.
    let mut a = vec![0.0; 4000];
    a[2000..].copy_from_slice(&sine(2000, 0.5, 6.0));
    let seg = SperlingParams {
        segment_s: Some(2.0),
        ..SperlingParams::default()
    };
    let wz = sperling_wz(&a, DT, &seg).unwrap();
    assert!(rel(wz, closed_form(50.0, 6.0)) < 1e-10, "{wz}");
    let whole = sperling_wz(&a, DT, &SperlingParams::default()).unwrap();
    assert!(whole < wz, "{whole} vs {wz}");
    // A segment longer than the window is refused, naming it.
    let long = SperlingParams {
        segment_s: Some(5.0),
        ..SperlingParams::default()
    };
    let e = sperling_wz(&a, DT, &long).unwrap_err().to_string();
    assert!(e.contains("Sperling segment (5 s"), "{e}");
}

/// A 1-s record with hand-made extremes.
struct Hand {
    p: [Vec<f64>; 4],
    z_c_a: Vec<f64>,
    beta_c_a: Vec<f64>,
    z_t_a: [Vec<f64>; 2],
    z_r: [Vec<f64>; 4],
}

const W: f64 = 70e3;
const L_C: f64 = 9.0;

impl Hand {
    fn new() -> Self {
        let n = 1000;
        let mut p1 = vec![W; n];
        p1[400] = 30e3; // the deepest unloading: (W - 30 kN) / W = 4/7
        let mut p3 = vec![W; n];
        p3[700] = 120e3; // the peak force
        p3[701] = 35e3;
        let p2: Vec<f64> = (0..n)
            .map(|k| W + 10e3 * (2.0 * std::f64::consts::PI * 5.0 * k as f64 * DT).sin())
            .collect();
        let mut z_c_a = vec![0.1; n];
        z_c_a[100] = -0.4;
        let mut beta_c_a = vec![0.0; n];
        beta_c_a[200] = 0.05; // at row 200 front 0.1 - 9 * 0.05 = -0.35, rear 0.55
        let mut t1 = vec![0.0; n];
        t1[10] = -3.0;
        let mut t2 = vec![1.0; n];
        t2[20] = 2.5;
        let mut r2 = vec![0.8e-3; n];
        r2[500] = 1.25e-3;
        Self {
            p: [p1, p2, p3, vec![W; n]],
            z_c_a,
            beta_c_a,
            z_t_a: [t1, t2],
            z_r: [vec![0.8e-3; n], r2, vec![-0.1e-3; n], vec![0.0; n]],
        }
    }

    fn record(&self) -> Record<'_> {
        Record {
            dt: DT,
            p: std::array::from_fn(|i| self.p[i].as_slice()),
            z_c_a: &self.z_c_a,
            beta_c_a: &self.beta_c_a,
            z_t_a: std::array::from_fn(|i| self.z_t_a[i].as_slice()),
            z_r: std::array::from_fn(|i| self.z_r[i].as_slice()),
        }
    }
}

fn cfg() -> IndexConfig {
    IndexParams::default().validate().unwrap()
}

#[test]
fn wheel_load_reduction_rate_of_a_hand_made_force_history() {
    let h = Hand::new();
    let ix = compute(&h.record(), L_C, W, &cfg()).unwrap();
    assert!(rel(ix.wheel_load_reduction_rate, 4.0 / 7.0) < 1e-15);
    assert_eq!(ix.peak_wheel_rail_force_kn, 120.0);
    // Without the dip the 5 Hz sinusoid of p_2 (10 kN) decides: 10/70 to the sine's
    // sampling (k = 150: sin(3 pi / 2) = -1 exactly on this grid, to rounding).
    let mut h2 = Hand::new();
    h2.p[0][400] = W;
    h2.p[2][701] = W;
    let ix = compute(&h2.record(), L_C, W, &cfg()).unwrap();
    assert!(rel(ix.wheel_load_reduction_rate, 1.0 / 7.0) < 1e-12);
    // A force above W everywhere gives a negative rate (the wheel is never unloaded).
    let p = vec![80e3; 1000];
    let z = vec![0.0; 1000];
    let rec = Record {
        dt: DT,
        p: [&p, &p, &p, &p],
        z_c_a: &z,
        beta_c_a: &z,
        z_t_a: [&z, &z],
        z_r: [&z, &z, &z, &z],
    };
    let ix = compute(&rec, L_C, W, &cfg()).unwrap();
    assert!(rel(ix.wheel_load_reduction_rate, -1.0 / 7.0) < 1e-15);
}

#[test]
fn indices_of_a_record_with_known_extremes() {
    let h = Hand::new();
    let ix = compute(&h.record(), L_C, W, &cfg()).unwrap();
    let [c, f, r] = ix.car_body_acc_peak_ms2;
    assert_eq!(c, 0.4);
    // Front: |-0.4| at row 100 beats |0.1 - 0.45| at row 200; rear: 0.1 + 0.45 at row 200.
    assert!(
        (f - 0.4).abs() < 1e-15 && (r - 0.55).abs() < 1e-15,
        "{f} {r}"
    );
    // RMS: 999 points of 0.1 and one of -0.4 at the centre.
    let rms_c = ((999.0 * 0.01 + 0.16) / 1000.0f64).sqrt();
    assert!(rel(ix.car_body_acc_rms_ms2[0], rms_c) < 1e-14);
    assert_eq!(ix.bogie_acc_peak_ms2, [3.0, 2.5]);
    assert!(rel(ix.rail_deflection_peak_mm, 1.25) < 1e-14);
    assert_eq!(ix.window_s, 1.0);
    // The values come out in INDEX_COLUMNS order.
    let v = ix.values();
    assert_eq!(v[0], ix.peak_wheel_rail_force_kn);
    assert_eq!(v[13], ix.rail_deflection_peak_mm);
    assert_eq!(INDEX_COLUMNS[0].name, "peak_wheel_rail_force_kn");
    let names: std::collections::BTreeSet<_> = INDEX_COLUMNS.iter().map(|c| c.name).collect();
    assert_eq!(names.len(), 14);
    // RMS of a sinusoid over whole periods is A / sqrt 2; its peak on this grid is A.
    let s = sine(1000, 0.3, 5.0);
    let z = vec![0.0; 1000];
    let p = vec![W; 1000];
    let rec = Record {
        dt: DT,
        p: [&p, &p, &p, &p],
        z_c_a: &s,
        beta_c_a: &z,
        z_t_a: [&z, &z],
        z_r: [&z, &z, &z, &z],
    };
    let ix = compute(&rec, L_C, W, &cfg()).unwrap();
    for k in 0..3 {
        assert!(rel(ix.car_body_acc_rms_ms2[k], 0.3 / 2f64.sqrt()) < 1e-12);
        assert!(rel(ix.car_body_acc_peak_ms2[k], 0.3) < 1e-12);
    }
    assert!(rel(ix.sperling_wz[0], closed_form(30.0, 5.0)) < 1e-10);
}

#[test]
fn the_window_drops_the_start_up() {
    let h = Hand::new();
    let c = IndexParams {
        window_start_fraction: 0.5,
        ..IndexParams::default()
    }
    .validate()
    .unwrap();
    let rec = h.record();
    let first = c.first_index(rec.len().unwrap());
    assert_eq!(first, 500);
    let ix = compute(&rec.tail(first), L_C, W, &c).unwrap();
    // The extremes before t = 0.5 s are gone (p_1's dip, the car-body and bogie spikes);
    // p_3's peak at 0.7 s and its drop to 35 kN right after stay.
    assert!(rel(ix.peak_wheel_rail_force_kn, 120.0) < 1e-15);
    assert!(rel(ix.wheel_load_reduction_rate, 0.5) < 1e-15);
    assert!(rel(ix.car_body_acc_peak_ms2[0], 0.1) < 1e-15);
    assert_eq!(ix.bogie_acc_peak_ms2, [0.0, 1.0]);
    assert_eq!(ix.window_s, 0.5);
}

#[test]
fn the_window_starts_at_the_later_of_the_fraction_and_indices_from() {
    let at = |fraction: f64, from_s: f64| IndexConfig {
        from_s,
        ..IndexParams {
            window_start_fraction: fraction,
            ..IndexParams::default()
        }
        .validate()
        .unwrap()
    };
    // A record of 1000 points at 1 ms from t = 0 (times summed as a solver stores them).
    let t: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-3).collect();
    assert_eq!(at(0.0, 0.0).first_row(&t), 0);
    assert_eq!(at(0.0, 0.2).first_row(&t), 200, "t = 0.2 s is read");
    assert_eq!(at(0.0, 0.2005).first_row(&t), 201);
    assert_eq!(
        at(0.5, 0.2).first_row(&t),
        500,
        "the fraction's start is later"
    );
    assert_eq!(at(0.1, 0.2).first_row(&t), 200, "indices_from is later");
    // A window that starts later (a model's, from t0 = 0.05 s): 150 points to 0.2 s.
    assert_eq!(at(0.0, 0.2).first_at(0.05, 1e-3), 150);
    assert_eq!(
        at(0.0, 0.2).first_at(0.3, 1e-3),
        0,
        "the window starts after it"
    );
    // Dropping those points drops the extremes before them, as the fraction does.
    let h = Hand::new();
    let rec = h.record();
    let first = at(0.0, 0.5).first_at(0.0, rec.dt);
    assert_eq!(first, 500);
    let ix = compute(&rec.tail(first), L_C, W, &cfg()).unwrap();
    assert!(rel(ix.wheel_load_reduction_rate, 0.5) < 1e-15);
    assert!(at(0.0, 0.2)
        .describe()
        .contains(&("indices_from_s", "0.2".to_owned())));
}

#[test]
fn limits_name_what_fails() {
    let h = Hand::new();
    let ix = compute(&h.record(), L_C, W, &cfg()).unwrap();
    // 4/7 = 0.571 < 0.6 passes; 120 kN < 170 passes.
    assert!(!cfg()
        .limits
        .failed(&ix)
        .contains(&"wheel_load_reduction_rate"));
    let strict = Limits {
        peak_wheel_rail_force_kn: Some(100.0),
        wheel_load_reduction_rate: Some(0.5),
        sperling_wz: None,
    };
    assert_eq!(
        strict.failed(&ix),
        vec!["peak_wheel_rail_force_kn", "wheel_load_reduction_rate"]
    );
}

#[test]
fn bad_input_is_named() {
    let mut h = Hand::new();
    h.z_t_a[1][7] = f64::NAN;
    let e = compute(&h.record(), L_C, W, &cfg())
        .unwrap_err()
        .to_string();
    assert!(e.contains("`z_t2_a`") && e.contains("row 7"), "{e}");
    let mut h = Hand::new();
    h.z_r[2].pop();
    let e = compute(&h.record(), L_C, W, &cfg())
        .unwrap_err()
        .to_string();
    assert!(e.contains("`z_r3` has 999 rows"), "{e}");
    let h = Hand::new();
    let e = compute(&h.record().tail(1000), L_C, W, &cfg())
        .unwrap_err()
        .to_string();
    assert!(e.contains("0 points"), "{e}");
    // Parameters: the field, its value and the allowed range.
    let e = IndexParams {
        window_start_fraction: 1.0,
        ..IndexParams::default()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("`window_start_fraction` = 1") && e.contains("[0, 1)"),
        "{e}"
    );
    let p: IndexParams =
        serde_yaml::from_str("sperling: {segment_s: -1}\nlimits: {sperling_wz: null}\n").unwrap();
    assert_eq!(p.limits.sperling_wz, None);
    assert_eq!(p.limits.wheel_load_reduction_rate, Some(0.6));
    let e = p.validate().unwrap_err().to_string();
    assert!(e.contains("sperling.segment_s"), "{e}");
    assert!(serde_yaml::from_str::<IndexParams>("windw_start_fraction: 0.1\n").is_err());
}
