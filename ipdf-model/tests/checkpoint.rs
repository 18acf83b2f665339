//! Checkpoints, resuming, pretrained backbones and bad input, through the public API.
use crate::common;

use std::path::Path;

use ipdf_model::rotation::{
    ENSEMBLE_FILE, ImplicitPdf, LabelledImages, QuerySampling, RotationFrame, TrainOptions,
    Trainer, write_ensemble,
};
use ipdf_model::{
    Augmentation, CHECKPOINT_FILE, CheckpointInfo, EncoderKind, FitOptions, ModelConfig,
    ModelError, TRAIN_LOG, load_backbone,
};
use nalgebra::{Quaternion, UnitQuaternion};
use tch::{Device, Kind, Tensor};

const SIZE: i64 = 16;

fn config() -> ModelConfig {
    ModelConfig {
        head_sizes: vec![16, 16],
        ..ModelConfig::small(SIZE)
    }
}

fn options() -> TrainOptions {
    TrainOptions {
        queries: QuerySampling::Uniform { count: 64 },
        augmentation: Augmentation::OCCLUSION,
        ..TrainOptions::default()
    }
}

fn data(count: usize) -> LabelledImages {
    let images = Tensor::rand([count as i64, 3, SIZE, SIZE], (Kind::Float, Device::Cpu));
    let sets = (0..count)
        .map(|i| vec![UnitQuaternion::from_euler_angles(0.1 * i as f64, 0.3, -0.2)])
        .collect();
    LabelledImages::new(images, sets).unwrap()
}

fn head_weight(model: &ImplicitPdf) -> Tensor {
    model.var_store().variables()["head.hidden.0.weight"].copy()
}

fn fit_options(epochs: u64) -> FitOptions {
    FitOptions {
        epochs,
        steps_per_epoch: 3,
        batch_size: 4,
        validation_level: 0,
    }
}

#[test]
fn a_resumed_run_ends_where_an_uninterrupted_one_does() {
    let data = data(10);
    let whole = tempfile::tempdir().unwrap();
    let split = tempfile::tempdir().unwrap();
    let fresh =
        || Trainer::new(ImplicitPdf::new(config(), Device::Cpu).unwrap(), options()).unwrap();
    let (trainer, reports, resumed) = common::uninterrupted_and_resumed(
        fresh,
        |dir| Trainer::resume(dir, Device::Cpu),
        &data,
        fit_options,
        3,
        (whole.path(), split.path()),
    );
    assert_eq!(reports.len(), 2);
    assert!(
        reports
            .iter()
            .all(|r| r.validation_llh.is_some_and(f64::is_finite))
    );

    assert_eq!(resumed.step(), trainer.step());
    assert!(head_weight(resumed.model()).equal(&head_weight(trainer.model())));
    let log = std::fs::read_to_string(split.path().join(TRAIN_LOG)).unwrap();
    assert_eq!(log.lines().count(), 3, "{log}");
    assert!(log.starts_with("epoch,step,loss,"));
    // Only the newest tensor files are kept.
    let files = std::fs::read_dir(split.path()).unwrap().count();
    assert_eq!(
        files, 4,
        "checkpoint.json, train_log.csv, model and optimizer files"
    );
}

#[test]
fn a_saved_model_loads_with_identical_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let model = ImplicitPdf::new(
        ModelConfig {
            seed: 4,
            ..config()
        },
        Device::Cpu,
    )
    .unwrap();
    model.save(dir.path()).unwrap();
    let loaded = ImplicitPdf::load(dir.path(), Device::Cpu).unwrap();
    let images = Tensor::rand([2, 3, SIZE, SIZE], (Kind::Float, Device::Cpu));
    let a = model.image_term(&images, false).unwrap();
    let b = loaded.image_term(&images, false).unwrap();
    assert!(a.equal(&b));
    let info = CheckpointInfo::read(dir.path()).unwrap();
    assert_eq!(info.model, *model.config());
    assert!(info.training.is_none());
}

#[test]
fn the_rotation_frame_is_kept_and_older_checkpoints_are_in_the_camera_frame() {
    let dir = tempfile::tempdir().unwrap();
    let line_of_sight = ModelConfig {
        rotation_frame: RotationFrame::LineOfSight,
        ..config()
    };
    ImplicitPdf::new(line_of_sight.clone(), Device::Cpu)
        .unwrap()
        .save(dir.path())
        .unwrap();
    let json = dir.path().join(CHECKPOINT_FILE);
    let text = std::fs::read_to_string(&json).unwrap();
    assert!(
        text.contains("\"rotation_frame\": \"line-of-sight\""),
        "{text}"
    );
    let loaded = ImplicitPdf::load(dir.path(), Device::Cpu).unwrap();
    assert_eq!(loaded.config().rotation_frame, RotationFrame::LineOfSight);
    // Resuming it as a camera-frame model is refused, naming the field.
    let err = config()
        .check_same(&loaded.config().clone(), &json)
        .unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::ConfigMismatch {
                field: "rotation_frame",
                ..
            }
        ),
        "{err}"
    );
    // A checkpoint written before the frame was recorded names none: the camera's.
    let older = text.replace(",\n    \"rotation_frame\": \"line-of-sight\"", "");
    assert!(!older.contains("rotation_frame"), "{older}");
    std::fs::write(&json, older).unwrap();
    let loaded = ImplicitPdf::load(dir.path(), Device::Cpu).unwrap();
    assert_eq!(loaded.config().rotation_frame, RotationFrame::Camera);
    // A camera-frame model writes no frame, as before.
    ImplicitPdf::new(config(), Device::Cpu)
        .unwrap()
        .save(dir.path())
        .unwrap();
    assert!(
        !std::fs::read_to_string(&json)
            .unwrap()
            .contains("rotation_frame")
    );
}

#[test]
fn damaged_or_foreign_checkpoints_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let model = ImplicitPdf::new(config(), Device::Cpu).unwrap();
    model.save(dir.path()).unwrap();
    let info = CheckpointInfo::read(dir.path()).unwrap();
    let weights = dir.path().join(&info.weights);

    // A checkpoint without training state cannot be resumed.
    let err = Trainer::resume(dir.path(), Device::Cpu).err().unwrap();
    assert!(matches!(err, ModelError::Checkpoint { .. }), "{err}");

    // Another configuration is named field by field.
    let other = ModelConfig {
        input_size: 24,
        ..config()
    };
    let err = other
        .check_same(&info.model, &dir.path().join(CHECKPOINT_FILE))
        .unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::ConfigMismatch {
                field: "input_size",
                ..
            }
        ),
        "{err}"
    );

    // Weights of another shape.
    let wide = ImplicitPdf::new(
        ModelConfig {
            head_sizes: vec![32, 16],
            ..config()
        },
        Device::Cpu,
    )
    .unwrap();
    let wide_dir = tempfile::tempdir().unwrap();
    wide.save(wide_dir.path()).unwrap();
    let wide_info = CheckpointInfo::read(wide_dir.path()).unwrap();
    std::fs::copy(wide_dir.path().join(&wide_info.weights), &weights).unwrap();
    let err = ImplicitPdf::load(dir.path(), Device::Cpu).unwrap_err();
    assert!(err.to_string().contains("head."), "{err}");

    // A truncated file.
    let bytes = std::fs::read(wide_dir.path().join(&wide_info.weights)).unwrap();
    std::fs::write(&weights, &bytes[..bytes.len() / 2]).unwrap();
    let err = ImplicitPdf::load(dir.path(), Device::Cpu).unwrap_err();
    assert!(matches!(err, ModelError::Checkpoint { .. }), "{err}");

    // Malformed JSON.
    std::fs::write(dir.path().join(CHECKPOINT_FILE), "{\"format\": 1").unwrap();
    let err = ImplicitPdf::load(dir.path(), Device::Cpu).unwrap_err();
    assert!(err.to_string().contains(CHECKPOINT_FILE), "{err}");
    // No checkpoint at all.
    let err = ImplicitPdf::load(Path::new("/nonexistent/run"), Device::Cpu).unwrap_err();
    assert!(matches!(err, ModelError::Io { .. }), "{err}");
}

#[test]
fn a_torchvision_named_backbone_loads_and_ignores_the_classifier() {
    let config = ModelConfig {
        encoder: EncoderKind::Resnet18,
        input_size: 32,
        head_sizes: vec![8],
        ..ModelConfig::default()
    };
    // A "pretrained" ResNet-18 state dict: another seed's weights under torchvision's names,
    // plus the classifier and batch-norm counters torchvision saves.
    let donor = ImplicitPdf::new(
        ModelConfig {
            seed: 7,
            ..config.clone()
        },
        Device::Cpu,
    )
    .unwrap();
    let mut state: Vec<(String, Tensor)> = donor
        .var_store()
        .variables()
        .into_iter()
        .filter_map(|(name, t)| name.strip_prefix("encoder.").map(|n| (n.to_string(), t)))
        .collect();
    assert!(state.iter().any(|(n, _)| n == "layer4.1.bn2.running_var"));
    state.push((
        "fc.weight".into(),
        Tensor::zeros([1000, 512], (Kind::Float, Device::Cpu)),
    ));
    state.push(("bn1.num_batches_tracked".into(), Tensor::from(5i64)));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("resnet18.safetensors");
    Tensor::write_safetensors(&state, &path).unwrap();

    let mut model = ImplicitPdf::new(config.clone(), Device::Cpu).unwrap();
    let loaded = load_backbone(&mut model, &path).unwrap();
    assert_eq!(loaded, state.len() - 2);
    let images = Tensor::rand([1, 3, 32, 32], (Kind::Float, Device::Cpu));
    let features = |m: &ImplicitPdf| m.image_term(&images, false).unwrap();
    // Every encoder tensor is the donor's now; the heads are still their own (seed 0 vs 7).
    let donor_vars = donor.var_store().variables();
    let mut model_vars = model.var_store().variables();
    let encoder: Vec<&String> = model_vars
        .keys()
        .filter(|n| n.starts_with("encoder."))
        .collect();
    assert_eq!(encoder.len(), loaded);
    for name in encoder {
        assert!(donor_vars[name].equal(&model_vars[name]), "{name}");
    }
    assert!(!features(&model).equal(&features(&donor)));
    // Through the donor's head, the model computes exactly what the donor computes: the image
    // path is the donor's, end to end.
    tch::no_grad(|| {
        for (name, tensor) in donor_vars.iter().filter(|(n, _)| n.starts_with("head.")) {
            model_vars.get_mut(name).unwrap().copy_(tensor);
        }
    });
    assert!(features(&model).equal(&features(&donor)));

    // A ConvNeXt model finds none of its tensors in a ResNet file.
    let mut convnext = ImplicitPdf::new(
        ModelConfig {
            encoder: EncoderKind::ConvnextTiny,
            ..config
        },
        Device::Cpu,
    )
    .unwrap();
    let err = load_backbone(&mut convnext, &path).unwrap_err();
    assert!(
        err.to_string()
            .contains("missing (the file holds no convnext-tiny weights)"),
        "{err}"
    );
}

#[test]
fn bad_images_and_labels_are_typed_errors() {
    let model = ImplicitPdf::new(config(), Device::Cpu).unwrap();
    let wrong_size = Tensor::rand([1, 3, SIZE + 1, SIZE], (Kind::Float, Device::Cpu));
    let grey = Tensor::rand([1, 1, SIZE, SIZE], (Kind::Float, Device::Cpu));
    for images in [wrong_size, grey] {
        let err = model.image_term(&images, false).unwrap_err();
        assert!(
            matches!(
                err,
                ModelError::ImageShape {
                    field: "images",
                    ..
                }
            ),
            "{err}"
        );
    }
    let mut trainer = Trainer::new(model, options()).unwrap();
    let images = Tensor::rand([2, 3, SIZE, SIZE], (Kind::Float, Device::Cpu));
    let one = vec![UnitQuaternion::identity()];
    let err = trainer
        .train_step(&images, &[one.clone(), vec![]])
        .unwrap_err();
    assert!(
        matches!(err, ModelError::LabelSet { image: 1, .. }),
        "{err}"
    );
    assert_eq!(err.to_string(), "label set 1: empty label set");
    let stretched = UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0));
    let err = trainer
        .train_step(&images, &[vec![one[0], stretched], one.clone()])
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "label set 0: label 1 is not a unit quaternion"
    );
    let err = trainer.train_step(&images, &[one]).unwrap_err();
    assert!(matches!(err, ModelError::LabelSet { .. }), "{err}");
    assert_eq!(trainer.step(), 0);
    let bad = TrainOptions {
        clip_norm: f64::NAN,
        ..options()
    };
    let model = ImplicitPdf::new(config(), Device::Cpu).unwrap();
    assert!(matches!(
        Trainer::new(model, bad),
        Err(ModelError::InvalidOption { .. })
    ));
    let err = ImplicitPdf::new(
        ModelConfig {
            input_size: 4,
            ..config()
        },
        Device::Cpu,
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::InvalidOption {
                name: "input_size",
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn an_ensemble_loads_the_members_its_file_names_and_refuses_a_bad_list() {
    let dir = tempfile::tempdir().unwrap();
    let at = |seed, input_size| {
        let config = ModelConfig {
            seed,
            input_size,
            ..config()
        };
        ImplicitPdf::new(config, Device::Cpu).unwrap()
    };
    at(0, SIZE).save(dir.path()).unwrap();
    let second = at(1, SIZE);
    second.save(&dir.path().join("member-2")).unwrap();
    // Without the file, the folder is one model.
    let load = || ImplicitPdf::load_ensemble(dir.path(), Device::Cpu);
    assert_eq!(load().unwrap().len(), 1);
    write_ensemble(dir.path(), &["member-2".into()]).unwrap();
    let members = load().unwrap();
    assert_eq!(members.len(), 2);
    assert!(head_weight(&members[1]).equal(&head_weight(&second)));
    assert!(!head_weight(&members[0]).equal(&head_weight(&second)));
    let refused = |text: &str, expected: &str| {
        std::fs::write(dir.path().join(ENSEMBLE_FILE), text).unwrap();
        let error = load().unwrap_err().to_string();
        assert!(error.contains(expected), "{text}: {error}");
    };
    refused(r#"{"members": 3}"#, "ensemble.json: members");
    refused(r#"{"members": ["member-3"]}"#, "member-3");
    at(2, 24).save(&dir.path().join("member-4")).unwrap();
    refused(r#"{"members": ["member-4"]}"#, "24-pixel crops");
    // Naming no member removes the file.
    write_ensemble(dir.path(), &[]).unwrap();
    assert!(!dir.path().join(ENSEMBLE_FILE).exists());
    assert_eq!(load().unwrap().len(), 1);
}
