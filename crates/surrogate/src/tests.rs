//! The surrogate's choice, its answers and its refusals, on two tiny models trained on one
//! synthetic dataset (and a third on another dataset).

use super::build::build;
use super::manifest::{Manifest, MEMBERS_DIR};
use super::Surrogate;
use candle_core::Device;
use learn_fixtures::synthetic::{write_dataset, SyntheticFiles, SyntheticSpec};
use pino_calibration::build::{calibrate, CalibrateParams};
use pino_calibration::{Calibration, HeadInput, ModelIdentity, Normaliser};
use pino_learn::config::TrainParams;
use pino_learn::spectral::Transform;
use pino_outputs::split::EvalData;
use pino_predict::{Predictor, ProfileChoice, ProfileSource};
use std::path::{Path, PathBuf};

fn spec(seed: u64) -> SyntheticSpec {
    SyntheticSpec {
        n_train: 2,
        n_validation: 2,
        n_test: 1,
        n_calibration: 4,
        duration: 0.3,
        seed,
        ..Default::default()
    }
}

/// The dataset of `spec(seed)` written into `dir`.
fn dataset(seed: u64, dir: &Path) -> SyntheticFiles {
    std::fs::create_dir_all(dir).unwrap();
    write_dataset(&spec(seed), dir).unwrap()
}

/// A model of `algorithm` trained for one epoch on `files` into `out`.
fn train(files: &SyntheticFiles, algorithm: i64, seed: u64, out: &Path) -> PathBuf {
    let layout = learn_fixtures::synthetic::vehicle_track_layout();
    let mut p = TrainParams::small(algorithm);
    p.epochs = 1;
    p.seed = seed;
    let (m, t, w) = p.configs(&layout).unwrap();
    let ds = files.load(&w, false).unwrap();
    std::fs::create_dir_all(out).unwrap();
    pino_learn::train::train_to_dir(
        &ds,
        (m, t, w),
        Transform::Fused,
        out,
        out,
        &Device::Cpu,
        &mut |_| {},
    )
    .unwrap();
    out.to_owned()
}

/// Calibrates `models` on `files` into `out`.
fn calibrate_all(files: &SyntheticFiles, models: &[PathBuf], out: &Path) {
    let info = files.info().unwrap();
    let sims = [files.simulation.clone()];
    let data = EvalData {
        info: &info,
        params_file: &files.params,
        simulation_files: &sims,
    };
    let params = CalibrateParams {
        normaliser: Normaliser::None,
        head_inputs: vec![HeadInput::Parameters],
        ridge: 1.0,
        batch_size: 2,
        device: pino_learn::config::DeviceKind::Cpu,
    };
    calibrate(&data, models, out, &params, &Device::Cpu, &mut |_, _| {}).unwrap();
}

struct Fixture {
    dir: tempfile::TempDir,
    files: SyntheticFiles,
    models: Vec<PathBuf>,
    calibrations: PathBuf,
}

/// Two candidates on one dataset: the FNO and algorithm 5 (different seeds), calibrated.
fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let files = dataset(3, &dir.path().join("data"));
    let models = vec![
        train(&files, 1, 1, &dir.path().join("a")),
        train(&files, 5, 2, &dir.path().join("b")),
    ];
    let calibrations = dir.path().join("cal");
    calibrate_all(&files, &models, &calibrations);
    Fixture {
        dir,
        files,
        models,
        calibrations,
    }
}

/// Sets the validation error of every quantity of `model`'s calibration: `pick(name)`.
fn set_errors(f: &Fixture, model: &Path, pick: impl Fn(&str) -> f64) {
    let identity = ModelIdentity::of(model).unwrap();
    let file = Calibration::find(&f.calibrations, &identity).unwrap();
    let mut cal = Calibration::load(&file, &identity).unwrap();
    for q in cal
        .indices
        .iter_mut()
        .chain(cal.channels.iter_mut().map(|c| &mut c.quantity))
    {
        let v = q.validation.as_mut().unwrap();
        v.mean_relative_pct = Some(pick(&q.name));
    }
    cal.write(file.parent().unwrap()).unwrap();
}

/// Validation errors under which the second candidate wins the quantities `special` (1 against
/// 9) and the first every other (2 against 5).
fn second_wins(f: &Fixture, special: &[&str]) {
    set_errors(f, &f.models[0], |n| {
        if special.contains(&n) {
            9.0
        } else {
            2.0
        }
    });
    set_errors(f, &f.models[1], |n| {
        if special.contains(&n) {
            1.0
        } else {
            5.0
        }
    });
}

#[test]
fn every_quantity_goes_to_the_candidate_with_the_lowest_validation_error() {
    let f = fixture();
    // Known errors: the second candidate wins the wheel-load index and the front wheel's
    // displacement, the first everything else.
    let special = ["wheel_load_reduction_rate", "z_w1"];
    second_wins(&f, &special);
    let out = f.dir.path().join("surrogate");
    let m = build(&f.models, &f.calibrations, &out).unwrap();
    let names: Vec<&str> = m.candidates.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["algorithm-1", "algorithm-5"]);
    assert!(!m.indices.is_empty() && !m.channels.is_empty());
    for r in m.indices.iter().chain(&m.channels) {
        let want = if special.contains(&r.name.as_str()) {
            "algorithm-5"
        } else {
            "algorithm-1"
        };
        assert_eq!(r.member, want, "{}: {:?}", r.name, r.validation);
        assert_eq!(r.validation.len(), 2);
    }
    assert!(m.channels.iter().any(|r| r.name == "z_w1"));
    assert_eq!(m.members.len(), 2);
    // The artifact holds both members' files and the routes' tables.
    for x in &m.members {
        let at = out.join(MEMBERS_DIR).join(&x.name);
        assert_eq!(ModelIdentity::of(&at).unwrap().blake3, x.model.blake3);
    }
    assert!(out.join("routes.csv").is_file() && out.join("routes.md").is_file());
    assert_eq!(Manifest::load(&out).unwrap(), m);
    // One candidate better everywhere: it alone is a member.
    set_errors(&f, &f.models[1], |_| 0.5);
    let only = build(&f.models, &f.calibrations, &f.dir.path().join("s2")).unwrap();
    assert_eq!(only.members.len(), 1);
    assert_eq!(only.members[0].name, "algorithm-5");
}

#[test]
fn the_surrogate_answers_as_its_routed_models_do() {
    let f = fixture();
    let special = ["peak_wheel_rail_force_kn", "p_1", "z_c_a"];
    second_wins(&f, &special);
    let out = f.dir.path().join("surrogate");
    build(&f.models, &f.calibrations, &out).unwrap();
    let dev = Device::Cpu;
    let s = Surrogate::load(&out, &dev).unwrap();
    let members: Vec<Predictor> = f
        .models
        .iter()
        .map(|d| {
            let mut p = Predictor::load(d, &dev).unwrap();
            p.load_calibration(&f.calibrations).unwrap();
            p
        })
        .collect();
    let primary = s.primary();
    let sets = vec![primary.space.nominal(), primary.space.nominal()];
    let profiles = primary
        .profiles(Some(&ProfileChoice::Generated { seed: 11, id: 0 }))
        .unwrap();
    let run = primary.run_config(None).unwrap();
    let cfg = primary.index_config().unwrap();
    let source = ProfileSource::Shared(&profiles);
    let got = s.answers(&sets, &source, &run, &cfg, 2, 0.75).unwrap();
    let own: Vec<_> = members
        .iter()
        .map(|p| p.answers(&sets, &source, &run, &cfg, 2, 0.75).unwrap())
        .collect();
    let routes = s.index_routes();
    let columns = primary.index_inputs().columns();
    assert_eq!(routes.len(), columns.len());
    for (k, c) in columns.iter().enumerate() {
        let m = if c.name == "peak_wheel_rail_force_kn" {
            1
        } else {
            0
        };
        assert_eq!(routes[k], ["algorithm-1", "algorithm-5"][m], "{}", c.name);
        for d in 0..sets.len() {
            assert_eq!(
                got[d].indices.values[k], own[m][d].indices.values[k],
                "{}",
                c.name
            );
            let (a, b) = (
                got[d].calibrated.as_ref().unwrap(),
                own[m][d].calibrated.as_ref().unwrap(),
            );
            assert_eq!(a.indices[k], b.indices[k], "{}", c.name);
            assert_eq!(a.verdicts[k], b.verdicts[k], "{}", c.name);
        }
    }
    // The histories: each channel and its band from its own member.
    let h = s.histories(&sets, &source, &run, 2, Some(0.75)).unwrap();
    let own_h: Vec<_> = members
        .iter()
        .map(|p| p.histories(&sets, &source, &run, 2, Some(0.75)).unwrap())
        .collect();
    for (name, m) in [("p_1", 1), ("z_c_a", 1), ("z_c", 0), ("z_w1_v", 0)] {
        for col in [name.to_owned(), format!("{name}_lo"), format!("{name}_hi")] {
            assert_eq!(h.f64(&col).unwrap(), own_h[m].f64(&col).unwrap(), "{col}");
        }
    }
    assert_eq!(h.num_rows(), own_h[0].num_rows());
    // A single model is a surrogate of one member answering everything as itself.
    let one = Surrogate::of_model(members.into_iter().next().unwrap());
    let alone = one.answers(&sets, &source, &run, &cfg, 2, 0.75).unwrap();
    assert_eq!(alone[0].indices, own[0][0].indices);
    assert_eq!(alone[0].calibrated, own[0][0].calibrated);
}

#[test]
fn changed_members_foreign_candidates_and_no_candidate_are_refused() {
    let f = fixture();
    let out = f.dir.path().join("surrogate");
    let m = build(&f.models, &f.calibrations, &out).unwrap();
    // A manifest of another system beside these members: refused naming it and the member.
    let file = out.join(super::manifest::SURROGATE_FILE);
    let text = std::fs::read_to_string(&file).unwrap();
    let mut other: Manifest = serde_json::from_str(&text).unwrap();
    other.system = "another-system".into();
    other.write(&out).unwrap();
    let err = Surrogate::load(&out, &Device::Cpu)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains(&file.display().to_string())
            && err.contains("`another-system`")
            && err.contains(&format!("member model `{}`", m.members[0].name)),
        "{err}"
    );
    std::fs::write(&file, text).unwrap();
    assert!(Surrogate::load(&out, &Device::Cpu).is_ok());
    // No candidate.
    let err = build(&[], &f.calibrations, &f.dir.path().join("none"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("candidates"), "{err}");
    // A member's weights changed after the build.
    let name = &m.members[0].name;
    let weights = out
        .join(MEMBERS_DIR)
        .join(name)
        .join(pino_calibration::MODEL_WEIGHTS);
    let mut bytes = std::fs::read(&weights).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&weights, bytes).unwrap();
    let err = Surrogate::load(&out, &Device::Cpu)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains(&weights.display().to_string()) && err.contains(name.as_str()),
        "{err}"
    );
    // A model trained on another dataset of the same description.
    let other = dataset(4, &f.dir.path().join("data2"));
    let foreign = train(&other, 2, 1, &f.dir.path().join("c"));
    let cal2 = f.dir.path().join("cal2");
    calibrate_all(&other, std::slice::from_ref(&foreign), &cal2);
    for entry in std::fs::read_dir(&cal2).unwrap() {
        let e = entry.unwrap().path();
        let to = f.calibrations.join(e.file_name().unwrap());
        std::fs::create_dir_all(&to).unwrap();
        std::fs::copy(e.join("calibration.json"), to.join("calibration.json")).unwrap();
    }
    let mut models = f.models.clone();
    models.push(foreign.clone());
    let err = build(&models, &f.calibrations, &f.dir.path().join("mixed"))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("another dataset") && err.contains(&foreign.display().to_string()),
        "{err}"
    );
    let _ = &f.files;
}
