//! What a pipeline run does: the presets, the plan with its overrides, and
//! `pipeline_config.json`, which records the settings a run folder was started with so that a
//! rerun with other settings is refused rather than mixed in.
use std::path::{Path, PathBuf};

use bop_dataset::{read_json, write_json};
use depth_render::SensorPreset;
use ipdf_model::EncoderKind;
use ipdf_model::rotation::RotationFrame;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::Error;
use crate::training::Target;

/// A size of run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Minutes on a laptop CPU: 800 training frames per object, a small CNN on 48-pixel crops.
    Quick,
    /// The paper's scale (GPU advised): 20,000 frames per variant, ResNet-18 on 224-pixel crops,
    /// 50 epochs of 200 steps of 64; with and without occlusion, and two more backbones.
    Paper,
    /// Minutes on one GPU: the paper's networks (ResNet-18 on 224-pixel crops, a 4 × 256 head)
    /// on 3,000 frames per object, 12 rotation and 4 translation epochs of 200 steps of 64.
    Gpu,
    /// The quick preset with an ImageNet-pretrained EfficientNet-Lite0 for the rotation model
    /// ([`PRETRAINED_WEIGHTS`], its stem and first 8 blocks frozen, 48 epochs at 1e-3): on the
    /// real YCB-Video frames it found a true pose as often as the quick preset and put the
    /// truth above uniform more often, for a third more time (docs/results.md, "Every instance
    /// with the pretrained encoder"). Measured with `--mesh` only.
    Pretrained,
}

/// Where `make setup` (scripts/setup-pretrained.sh) puts EfficientNet-Lite0's ImageNet
/// weights, relative to the repository's root: the pretrained preset's weights.
pub const PRETRAINED_WEIGHTS: &str = ".pretrained/efficientnet-lite0.safetensors";

impl Preset {
    /// Every preset.
    pub const ALL: [Self; 4] = [Self::Quick, Self::Paper, Self::Gpu, Self::Pretrained];

    /// `quick`, `paper`, `gpu` or `pretrained`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Quick => "quick",
            Self::Paper => "paper",
            Self::Gpu => "gpu",
            Self::Pretrained => "pretrained",
        }
    }

    /// What the preset is for, in a line.
    pub fn description(self) -> &'static str {
        match self {
            Self::Quick => {
                "minutes on a CPU: a small CNN on 48-pixel crops (with --mesh a deeper one on 64)"
            }
            Self::Paper => {
                "the paper's scale, for a GPU: ResNet-18 on 224-pixel crops, 20,000 frames \
                 per variant, 50 epochs of 200 x 64"
            }
            Self::Gpu => {
                "the paper's networks in minutes on one GPU: 3,000 frames per object, 12 \
                 rotation and 4 translation epochs of 200 x 64"
            }
            Self::Pretrained => {
                "with --mesh: the quick preset's run, its rotation model an ImageNet \
                 efficientnet-lite0 (weights from `make setup`); about a third longer"
            }
        }
    }

    /// What the preset runs.
    pub fn plan(self) -> Plan {
        match self {
            Self::Quick => Plan {
                preset: self,
                frames: 800,
                val_frames: 50,
                texture_frames: 20,
                sensor: Some(SensorPreset::Kinect),
                encoder: EncoderKind::SmallCnn,
                input_size: 48,
                head: vec![64, 64],
                epochs: 32,
                translation_epochs: 16,
                steps_per_epoch: 50,
                batch_size: 16,
                learning_rate: 4e-3,
                translation_learning_rate: 2e-3,
                query_level: 1,
                translation_queries: 512,
                eval_level: 5,
                occlusion: vec![false],
                blur: 0.0,
                appearance_margin: 0.0,
                backbones: vec![],
                rotation_frame: RotationFrame::Camera,
                rotation_members: 1,
                translation_encoder: None,
                pretrained: None,
                frozen_blocks: 0,
                concurrent_models: 2,
            },
            Self::Paper => Plan {
                preset: self,
                frames: 6667,
                val_frames: 500,
                texture_frames: 6667,
                sensor: Some(SensorPreset::Kinect),
                encoder: EncoderKind::Resnet18,
                input_size: 224,
                head: vec![256, 256, 256, 256],
                epochs: 50,
                translation_epochs: 50,
                steps_per_epoch: 200,
                batch_size: 64,
                learning_rate: 1e-4,
                translation_learning_rate: 1e-4,
                query_level: 2,
                translation_queries: 4_096,
                eval_level: 5,
                occlusion: vec![false, true],
                blur: 0.0,
                appearance_margin: 0.0,
                backbones: vec![EncoderKind::Resnet18Stage3, EncoderKind::ConvnextTiny],
                rotation_frame: RotationFrame::Camera,
                rotation_members: 1,
                translation_encoder: None,
                pretrained: None,
                frozen_blocks: 0,
                concurrent_models: 1,
            },
            Self::Gpu => Plan {
                preset: self,
                frames: 3000,
                val_frames: 100,
                texture_frames: 100,
                epochs: 12,
                translation_epochs: 4,
                occlusion: vec![false],
                backbones: vec![],
                ..Self::Paper.plan()
            },
            // The built-in objects' run with the same encoder: not measured, and `ipdf
            // pipeline` takes this preset with `--mesh` only.
            Self::Pretrained => imagenet_encoder(Self::Quick.plan()),
        }
    }

    /// What the preset runs for one mesh of the user's (`ipdf pipeline --mesh`): randomised
    /// renders of it, and a Pseudo rotation and translation model trained with occlusion and
    /// blur on them. Measured on the real YCB-Video frames (docs/experiments.md), the quick
    /// preset's 48-pixel crops, 800 frames and 32 epochs learnt the demo's shapes but not a
    /// real object: 64-pixel crops, 2,000 frames, occlusion and blur are what the cracker
    /// box's real frames answered to, and 128 rotation epochs rather than 64 place a sugar
    /// box's validation renders within 15° half as often again (51% from 39%); the deep small
    /// CNN scored seven objects' validation renders higher than the plain one (LLH 2.77 → 3.47)
    /// for half as much training time again (docs/experiments.md, "A deeper small CNN"). The GPU
    /// preset's run is the one measured on an H200 (5.7–6.1 minutes per object) but for the
    /// frame: every mesh preset's rotation model learns in the line of sight's, since the
    /// renders place the object anywhere in the image and nine of the ten YCB-Video objects'
    /// validation renders scored higher so (docs/experiments.md, "Rotations in the line of
    /// sight's frame").
    pub fn mesh_plan(self) -> Plan {
        let base = Plan {
            rotation_frame: RotationFrame::LineOfSight,
            ..self.plan()
        };
        match self {
            Self::Quick => Plan {
                frames: 2000,
                texture_frames: 0,
                encoder: EncoderKind::SmallCnnDeep,
                input_size: 64,
                epochs: 128,
                translation_epochs: 32,
                eval_level: 4,
                occlusion: vec![true],
                blur: 1.5,
                ..base
            },
            Self::Paper => Plan {
                frames: 20_000,
                texture_frames: 0,
                occlusion: vec![true],
                blur: 1.5,
                backbones: vec![],
                ..base
            },
            Self::Gpu => Plan {
                texture_frames: 0,
                occlusion: vec![true],
                blur: 1.5,
                ..base
            },
            // The translation model keeps the quick preset's deep small CNN: the ImageNet
            // encoder's were no nearer (docs/experiments.md).
            Self::Pretrained => Plan {
                translation_encoder: Some(EncoderKind::SmallCnnDeep),
                ..imagenet_encoder(Self::Quick.mesh_plan())
            },
        }
    }
}

/// `quick`, the quick preset's plan, with the pretrained preset's rotation encoder: Lite0 from
/// [`PRETRAINED_WEIGHTS`] with its stem and first 8 blocks frozen, 48 epochs at 1e-3 (the
/// configuration docs/results.md measures).
fn imagenet_encoder(quick: Plan) -> Plan {
    Plan {
        preset: Preset::Pretrained,
        encoder: EncoderKind::EfficientnetLite0,
        pretrained: Some(PRETRAINED_WEIGHTS.into()),
        frozen_blocks: 8,
        epochs: 48,
        learning_rate: 1e-3,
        ..quick
    }
}

/// What a run does: a preset's plan, possibly with frames and epochs overridden. Serialised
/// (with the seed) as `pipeline_config.json` and the `"config"` of `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The preset it started from.
    pub preset: Preset,
    /// Training frames per object of the uniform dataset.
    #[serde(rename = "frames_per_object")]
    pub frames: usize,
    /// Validation frames per object of the uniform dataset.
    #[serde(rename = "val_frames_per_object")]
    pub val_frames: usize,
    /// Frames per object of the textured dataset (labelled, not trained on).
    #[serde(rename = "texture_frames_per_object")]
    pub texture_frames: usize,
    /// The depth camera whose readings the datasets' depth imitates and the labelling expects
    /// (both presets: a Kinect v1, as T-LESS's Primesense); `None` (`--clean-depth`): clean
    /// rendered depth. The colour images, masks and ground truth do not depend on it: only the
    /// pseudo labels do.
    pub sensor: Option<SensorPreset>,
    /// The encoder of the Single / Analytical / Pseudo models.
    pub encoder: EncoderKind,
    /// Side of the square crops (pixels).
    pub input_size: usize,
    /// Widths of the head's layers (written comma-separated, as `--head` takes them).
    #[serde(with = "comma_separated")]
    pub head: Vec<i64>,
    /// Epochs of the rotation models.
    pub epochs: u64,
    /// Epochs of the translation models.
    pub translation_epochs: u64,
    /// Steps per epoch.
    pub steps_per_epoch: u64,
    /// Images per step.
    pub batch_size: usize,
    /// Peak learning rate of the rotation models.
    pub learning_rate: f64,
    /// Peak learning rate of the translation models.
    pub translation_learning_rate: f64,
    /// Grid level of the training queries.
    pub query_level: u8,
    /// Translations queried per image and step by the translation models (one beside each
    /// Single / Analytical / Pseudo rotation model, in its `translation/` folder).
    pub translation_queries: usize,
    /// Grid level of the scores.
    pub eval_level: u8,
    /// Occlusion settings of the Single / Analytical / Pseudo models.
    pub occlusion: Vec<bool>,
    /// Largest blur of the training crops' augmentation (crop pixels; 0: none).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub blur: f64,
    /// The labeller's colour margin (`ipdf label --appearance-margin`; 0: off, every preset).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub appearance_margin: f64,
    /// Encoders also trained on pseudo labels (the paper's backbone comparison).
    pub backbones: Vec<EncoderKind>,
    /// The frame the rotation models learn in; the camera's where a run folder records none.
    #[serde(default)]
    pub rotation_frame: RotationFrame,
    /// Rotation models per ensemble (`ipdf train --members`); one where a run folder records
    /// none.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub rotation_members: usize,
    /// The translation models' encoder where it is not `encoder` (`--mesh` runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation_encoder: Option<EncoderKind>,
    /// Weights the encoder starts from (`ipdf train --pretrained`; `--mesh` runs): every model
    /// of the plan's `encoder` loads them. `None`: the seeded initial weights.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pretrained: Option<PathBuf>,
    /// The encoder's stem and first blocks kept as `pretrained` gives them (`ipdf train
    /// --freeze-encoder`).
    #[serde(default, skip_serializing_if = "is_zero_count")]
    pub frozen_blocks: usize,
    /// Models trained at once, each on one CPU thread: small models leave a second core
    /// partly idle, so two at a time finish sooner than one on two threads. How, not what: not
    /// recorded.
    #[serde(skip, default = "one")]
    pub concurrent_models: usize,
}

/// Serde's default of a count that was 1 before the file recorded it.
pub(crate) fn one() -> usize {
    1
}

/// Serde's test for leaving out such a count when it is 1.
pub(crate) fn is_one(value: &usize) -> bool {
    *value == 1
}

fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

fn is_zero_count(value: &usize) -> bool {
    *value == 0
}

/// `head` as `"64,64"`.
mod comma_separated {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    pub fn serialize<S: Serializer>(widths: &[i64], serializer: S) -> Result<S::Ok, S::Error> {
        let text: Vec<String> = widths.iter().map(i64::to_string).collect();
        serializer.serialize_str(&text.join(","))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<i64>, D::Error> {
        String::deserialize(deserializer)?
            .split(',')
            .map(|w| w.trim().parse::<i64>().map_err(D::Error::custom))
            .collect()
    }
}

impl Plan {
    /// The depth sensor the labeller and the pose refined with depth count errors in: the
    /// renders' sensor, or with clean depth the labeller's default.
    pub fn depth_sensor(&self) -> SensorPreset {
        self.sensor
            .unwrap_or(pseudo_label::LabelOptions::default().sensor)
    }

    /// Epochs the models of `target` train for.
    pub fn epochs_of(&self, target: Target) -> u64 {
        match target {
            Target::Translation => self.translation_epochs,
            _ => self.epochs,
        }
    }

    /// The encoder of the models of `target`.
    pub fn encoder_of(&self, target: Target) -> EncoderKind {
        match target {
            Target::Translation => self.translation_encoder.unwrap_or(self.encoder),
            _ => self.encoder,
        }
    }

    /// Peak learning rate of the models of `target`.
    pub fn learning_rate_of(&self, target: Target) -> f64 {
        match target {
            Target::Translation => self.translation_learning_rate,
            _ => self.learning_rate,
        }
    }

    /// Members of each model of `target`: the plan's for rotation models, one for translation
    /// models (only rotation models form ensembles).
    pub fn members_of(&self, target: Target) -> usize {
        match target {
            Target::Translation => 1,
            _ => self.rotation_members,
        }
    }

    /// Steps each model of `target` trains for.
    pub fn total_steps(&self, target: Target) -> u64 {
        self.epochs_of(target) * self.steps_per_epoch
    }

    /// The settings that decide the run's outputs, as recorded.
    pub fn config(&self, seed: u64) -> PipelineConfig {
        PipelineConfig {
            plan: self.clone(),
            seed,
            training_data: "uniform".into(),
        }
    }
}

/// `pipeline_config.json`, and the `"config"` of `report.json`: the plan, the seed and the
/// dataset trained on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PipelineConfig {
    /// What the run does.
    #[serde(flatten)]
    pub plan: Plan,
    /// The run's seed.
    pub seed: u64,
    /// The dataset trained on.
    pub training_data: String,
}

/// The file in the run folder recording the settings the run was started with.
pub const CONFIG_FILE: &str = "pipeline_config.json";

/// The keys of [`PipelineConfig`] set by command-line flags, and the flags.
const FLAGS: [(&str, &str); 24] = [
    ("preset", "--preset"),
    ("seed", "--seed"),
    ("mesh", "--mesh"),
    ("mesh_scale", "--mesh-scale"),
    ("camera", "--camera"),
    ("distance_m", "--distance"),
    ("randomize", "--randomize"),
    ("placement", "--placement"),
    ("real", "--real, --real-split and --obj-id"),
    ("frames_per_object", "--frames"),
    ("val_frames_per_object", "--val-frames"),
    ("texture_frames_per_object", "--texture-frames"),
    ("sensor", "--sensor or --clean-depth"),
    ("epochs", "--epochs"),
    ("translation_epochs", "--translation-epochs"),
    ("steps_per_epoch", "--steps-per-epoch"),
    ("encoder", "--encoder"),
    ("translation_encoder", "--translation-encoder"),
    ("pretrained", "--pretrained"),
    ("frozen_blocks", "--freeze-encoder"),
    ("learning_rate", "--learning-rate"),
    ("translation_learning_rate", "--translation-learning-rate"),
    ("rotation_frame", "--rotation-frame"),
    ("rotation_members", "--rotation-members"),
];

/// Keys recorded only since a later version, with the value every run before it had: a run
/// folder without the key was made with that value.
const ADDED_LATER: [(&str, &str); 2] = [("placement", "arranged"), ("rotation_frame", "camera")];

/// The command-line flag that sets a key of [`PipelineConfig`], for error messages.
fn flag_of(key: &str) -> String {
    let flag = FLAGS
        .iter()
        .find(|f| f.0 == key)
        .map_or("set by --preset", |f| f.1);
    format!(" ({flag})")
}

/// Refuses a run folder whose recorded settings differ from `config`, naming the first that
/// does (the settings given on the command line first): `pipeline_config.json`, or for a
/// folder from an older version without one, the `"config"` of its `report.json`. A folder with
/// neither is a new run: the folder is created and `config` recorded.
pub fn check_and_record(out: &Path, config: &impl Serialize) -> Result<(), Error> {
    std::fs::create_dir_all(out)
        .map_err(|e| bop_dataset::FileError::new(out, "folder", e.to_string()))?;
    let config_path = out.join(CONFIG_FILE);
    let report_path = out.join("report.json");
    let (path, recorded) = if config_path.exists() {
        (&config_path, read_json(&config_path)?)
    } else if report_path.exists() {
        (&report_path, read_json(&report_path)?["config"].clone())
    } else {
        return Ok(write_json(&config_path, config)?);
    };
    let expected =
        serde_json::to_value(config).map_err(|e| Error::option("config", e.to_string()))?;
    let (Some(recorded), Some(expected)) = (recorded.as_object(), expected.as_object()) else {
        return Err(Error::option(
            "config",
            format!("{}: not a JSON object", path.display()),
        ));
    };
    let first = FLAGS.iter().map(|&(key, _)| key);
    let rest = expected
        .keys()
        .map(String::as_str)
        .filter(|key| !FLAGS.iter().any(|f| f.0 == *key));
    for key in first.chain(rest) {
        let Some(value) = expected.get(key) else {
            continue;
        };
        // Keys an older report.json lacks are not compared; a key added later stands for the
        // value runs had before it.
        let earlier = ADDED_LATER
            .iter()
            .find(|added| added.0 == key)
            .map(|added| Value::from(added.1));
        let missing = if path == &config_path {
            Some(earlier.unwrap_or(Value::Null))
        } else {
            earlier
        };
        let Some(found) = recorded.get(key).cloned().or(missing) else {
            continue;
        };
        if &found != value {
            return Err(Error::option(
                "config",
                format!(
                    "{}: {key}{}: the run in {} was made with {found}, this run asks for \
                     {value}; rerun with the same settings to resume it, or choose another --out",
                    path.display(),
                    flag_of(key),
                    out.display()
                ),
            ));
        }
    }
    Ok(write_json(&config_path, config)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_run_recorded_before_a_key_existed_resumes_with_the_value_it_had() {
        let dir = tempfile::tempdir().unwrap();
        // A mesh run's settings as recorded before `placement` was: its renders were arranged.
        let before = json!({"preset": "quick", "seed": 0, "frames_per_object": 2000});
        std::fs::write(dir.path().join(CONFIG_FILE), before.to_string()).unwrap();
        let mut now = before.clone();
        now["placement"] = "leaning".into();
        let refused = check_and_record(dir.path(), &now).unwrap_err().to_string();
        assert!(refused.contains("placement (--placement)"), "{refused}");
        assert!(refused.contains("made with \"arranged\""), "{refused}");
        now["placement"] = "arranged".into();
        check_and_record(dir.path(), &now).unwrap();
        // Resumed, the record now names it; any other key still missing stays refused.
        let recorded: Value = read_json(&dir.path().join(CONFIG_FILE)).unwrap();
        assert_eq!(recorded["placement"], "arranged");
        now["blur"] = 1.5.into();
        let refused = check_and_record(dir.path(), &now).unwrap_err().to_string();
        assert!(refused.contains("made with null"), "{refused}");
    }

    #[test]
    fn a_run_recorded_without_a_rotation_frame_was_trained_in_the_camera_frame() {
        let dir = tempfile::tempdir().unwrap();
        let before = json!({"preset": "quick", "seed": 0, "placement": "arranged"});
        std::fs::write(dir.path().join(CONFIG_FILE), before.to_string()).unwrap();
        // Today's mesh plan records the line of sight's frame, the built-in objects' plan the
        // camera's.
        let plan = Preset::Quick.mesh_plan();
        assert_eq!(plan.rotation_frame, RotationFrame::LineOfSight);
        let recorded = serde_json::to_value(plan.config(0)).unwrap();
        assert_eq!(recorded["rotation_frame"], "line-of-sight");
        let camera = serde_json::to_value(Preset::Quick.plan().config(0)).unwrap();
        assert_eq!(camera["rotation_frame"], "camera");
        let mut now = before.clone();
        now["rotation_frame"] = recorded["rotation_frame"].clone();
        let refused = check_and_record(dir.path(), &now).unwrap_err().to_string();
        assert!(
            refused.contains("rotation_frame (--rotation-frame)")
                && refused.contains("made with \"camera\""),
            "{refused}"
        );
        // `--rotation-frame camera` resumes it, and the record now names the frame: a run in
        // the line of sight's is refused there.
        now["rotation_frame"] = "camera".into();
        check_and_record(dir.path(), &now).unwrap();
        now["rotation_frame"] = "line-of-sight".into();
        assert!(check_and_record(dir.path(), &now).is_err());
    }
}
