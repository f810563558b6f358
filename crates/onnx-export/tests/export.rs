//! The exporter on a small trained and calibrated vehicle-track model (`learn_fixtures`):
//! the file is a model of the declared inputs, outputs and metadata; a model without a
//! calibration exports without intervals and says why; refusals name their culprit and leave
//! no file. That the graph answers as `predict` does is checked in ONNX Runtime
//! (`tests/interop/onnx.rs`). With `ONNX_EXPORT_KEEP=DIR` the model, its calibration and the
//! exported files are kept in DIR.

use candle_core::Device;
use learn_fixtures::synthetic::{write_dataset, SyntheticSpec};
use onnx_export::{build, export, ExportSpec, Spectral};
use pino_calibration::build::{calibrate, CalibrateParams};
use pino_calibration::{HeadInput, Normaliser};
use pino_learn::config::TrainParams;
use pino_learn::data::DatasetInfo;
use pino_learn::spectral::Transform;
use pino_outputs::split::EvalData;
use std::path::{Path, PathBuf};

/// A model of 2 epochs and its calibration (12 samples: levels up to 12/13).
fn trained(dir: &Path) -> (PathBuf, PathBuf) {
    let spec = SyntheticSpec {
        n_train: 4,
        n_validation: 3,
        n_test: 2,
        n_calibration: 12,
        duration: 0.3,
        ..Default::default()
    };
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let files = write_dataset(&spec, &data).unwrap();
    let layout = learn_fixtures::synthetic::vehicle_track_layout();
    let mut p = TrainParams::small(2);
    (p.epochs, p.padding) = (2, 25);
    let (m, t, w) = p.configs(&layout).unwrap();
    let ds = files.load(&w, false).unwrap();
    let model = dir.join("model");
    std::fs::create_dir_all(&model).unwrap();
    let dev = Device::Cpu;
    pino_learn::train::train_to_dir(
        &ds,
        (m, t, w),
        Transform::Fused,
        &model,
        &model,
        &dev,
        &mut |_| {},
    )
    .unwrap();
    let info = DatasetInfo::from_dirs(std::slice::from_ref(&data)).unwrap();
    let cal = dir.join("calibration");
    std::fs::create_dir_all(&cal).unwrap();
    let params = CalibrateParams {
        normaliser: Normaliser::ErrorHead,
        head_inputs: vec![HeadInput::Residual],
        ridge: 1.0,
        batch_size: 4,
        device: pino_learn::config::DeviceKind::Cpu,
    };
    let eval = EvalData {
        info: &info,
        params_file: &files.params,
        simulation_files: std::slice::from_ref(&files.simulation),
    };
    calibrate(
        &eval,
        std::slice::from_ref(&model),
        &cal,
        &params,
        &dev,
        &mut |_, _| {},
    )
    .unwrap();
    (model, cal)
}

fn contains(bytes: &[u8], what: &str) -> bool {
    bytes.windows(what.len()).any(|w| w == what.as_bytes())
}

#[test]
fn a_calibrated_model_exports_with_its_intervals_and_refusals_leave_no_file() {
    let tmp = tempfile::tempdir().unwrap();
    let keep = std::env::var_os("ONNX_EXPORT_KEEP").map(PathBuf::from);
    let dir = keep.clone().unwrap_or_else(|| tmp.path().to_owned());
    std::fs::create_dir_all(&dir).unwrap();
    let (model, cal) = trained(&dir);

    let spec = ExportSpec::single(&model, Some(&cal));
    let out = build(&spec).unwrap();
    let s = &out.summary;
    // The vehicle track's 14 railway indices, every output and DOF rate, levels 0.8 and 0.9
    // (0.95 is above 12/13), normaliser `none` (the calibration's heads read the residual).
    assert_eq!(s.indices.len(), 14, "{:?}", s.left_out);
    assert!(s.left_out.is_empty());
    assert_eq!(s.channels.len(), 18 + 20);
    assert_eq!(
        (s.levels.clone(), s.normaliser),
        (vec![0.8, 0.9], Some(Normaliser::None))
    );
    for name in [
        "parameters",
        "excitation",
        "channels",
        "channels_lo",
        "indices_hi",
        "verdicts",
        "outside_training_range",
        "extrapolated",
        "pino.surrogate",
        "pino.system_hash",
        "\"recipe\"",
        "peak_wheel_rail_force_kn",
        "DFT",
        "MatMul",
    ] {
        let want = name != "DFT";
        assert_eq!(contains(&out.bytes, name), want, "{name}");
    }
    let path = dir.join("model.onnx");
    export(&spec, &path).unwrap();
    assert_eq!(
        std::fs::read(&path).unwrap(),
        out.bytes,
        "the export is deterministic"
    );

    // The DFT form (opset 17) has no fixed basis of the spectral layers.
    let dft = build(&ExportSpec {
        spectral: Spectral::Dft,
        ..spec.clone()
    })
    .unwrap();
    assert!(contains(&dft.bytes, "DFT") && dft.bytes.len() < out.bytes.len());
    std::fs::write(dir.join("model-dft.onnx"), &dft.bytes).unwrap();

    // Without a calibration: no interval outputs, and the metadata says why.
    let bare = build(&ExportSpec::single(&model, None)).unwrap();
    assert!(bare.summary.levels.is_empty());
    assert_eq!(
        bare.summary.no_intervals.as_deref(),
        Some("member `algorithm-2` has no calibration")
    );
    assert!(!contains(&bare.bytes, "channels_lo") && contains(&bare.bytes, "\"why\""));

    // Refusals name their culprit; the target is never written.
    let target = dir.join("refused.onnx");
    for (spec, needle) in [
        (
            ExportSpec {
                levels: Some(vec![0.95]),
                ..spec.clone()
            },
            "level 0.95",
        ),
        (
            ExportSpec {
                normaliser: Some(Normaliser::Residual),
                ..spec.clone()
            },
            "normaliser `residual`",
        ),
        (
            ExportSpec {
                normaliser: Some(Normaliser::ErrorHead),
                ..spec.clone()
            },
            "normaliser `error_head`",
        ),
        (
            ExportSpec {
                indices: Some(vec!["comfort".into()]),
                ..spec.clone()
            },
            "index `comfort`",
        ),
        (ExportSpec::single(&dir.join("nothing"), None), "nothing"),
    ] {
        let e = export(&spec, &target).unwrap_err().to_string();
        assert!(e.contains(needle), "{e}");
        assert!(!target.exists());
    }
    let e = export(&spec, Path::new("/nonexistent/dir/m.onnx"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/dir/m.onnx"), "{e}");
    // A subset of the indices, by name.
    let some = build(&ExportSpec {
        indices: Some(vec![
            "sperling_wz_front".into(),
            "peak_wheel_rail_force_kn".into(),
        ]),
        ..spec
    })
    .unwrap();
    assert_eq!(
        some.summary.indices,
        ["peak_wheel_rail_force_kn", "sperling_wz_front"]
    );
}
