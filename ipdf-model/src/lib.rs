//! Implicit-PDF (Murphy et al., ICML 2021) on libtorch through `tch`: image-conditioned,
//! unnormalised log-densities trained on *sets* of labels, so that a model learns every pose an
//! object is indistinguishable under.
//!
//! Two halves of the same shape, each with its model, training, training data and prediction:
//! - [`rotation`]: `F(R, I)` over SO(3) ([`rotation::ImplicitPdf`], [`rotation::Trainer`],
//!   [`rotation::Predictor`]), in the camera's frame or the line of sight's through the crop's
//!   centre ([`rotation::RotationFrame`]);
//! - [`translation`]: `F(t, I)` over the object's translation in the camera frame (mm),
//!   conditioned on the crop and where it was cut ([`translation::TranslationPdf`],
//!   [`translation::TranslationTrainer`], [`translation::TranslationPredictor`]).
//!
//! What both share lives at the root: the network's configuration ([`ModelConfig`]: encoders
//! with torchvision names — ResNet-18, ResNet-18 cut after stage 3, ConvNeXt-Tiny, a small CNN —
//! and [`load_backbone`] for pretrained `.safetensors`), crops ([`crop_object`] around a mask, [`crop_in_box`] in a detector's [`ImageBox`], [`CropBox`]),
//! augmentation, the optimiser ([`LearningRateSchedule`], [`StepReport`]), the epoch loop
//! ([`fit`]: validation LLH, `train_log.csv`, checkpoints that resume), checkpoints
//! ([`CheckpointInfo`]: `.safetensors` + JSON, atomic), best-first refinement of a cell
//! hierarchy ([`refine`], [`refine_on`]: the SO(3) grid and the translation octree), and the CPU
//! kernel settings that make runs reproducible ([`REPRODUCIBLE_CPU_KERNELS`]).
//!
//! ```
//! use ipdf_model::rotation::{ImplicitPdf, Predictor, TrainOptions, Trainer};
//! use ipdf_model::{ModelConfig, RefineOptions};
//! use nalgebra::UnitQuaternion;
//! use tch::{Device, Kind, Tensor};
//!
//! let model = ImplicitPdf::new(ModelConfig::small(32), Device::Cpu)?;
//! let mut trainer = Trainer::new(model, TrainOptions::default())?;
//! let images = Tensor::rand([2, 3, 32, 32], (Kind::Float, Device::Cpu));
//! // The first image looks the same under a half turn about z: both rotations are labels.
//! let half_turn = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::PI);
//! let labels = vec![vec![UnitQuaternion::identity(), half_turn], vec![half_turn]];
//! let report = trainer.train_step(&images, &labels)?;
//! assert!(report.loss.is_finite());
//!
//! let model = trainer.into_model();
//! let mut predictor = Predictor::new(&model);
//! let masses = predictor.probabilities(&images.get(0), 1)?; // 576 cells
//! assert!((masses.iter().sum::<f64>() - 1.0).abs() < 1e-6);
//! let refined = predictor.hierarchical(&images.get(0), &RefineOptions { level: 3, ..Default::default() })?;
//! assert!(refined.queries <= RefineOptions::default().max_queries);
//! // ln p(R | I) at any rotation, with the refined distribution's normaliser.
//! let log_density = predictor.log_densities(&images.get(0), &[half_turn], &refined)?;
//! assert!(log_density[0].is_finite());
//! # Ok::<(), ipdf_model::ModelError>(())
//! ```
//!
//! Translations: crops with where they were cut, labels in mm.
//!
//! ```
//! use ipdf_model::CropBox;
//! use ipdf_model::translation::{
//!     CameraIntrinsics, CropGeometry, TranslationConfig, TranslationPdf, TranslationPredictor,
//!     TranslationSpace, TranslationTrainOptions, TranslationTrainer,
//! };
//! use nalgebra::Vector3;
//! use tch::{Device, Kind, Tensor};
//!
//! let camera = CameraIntrinsics { fx: 600.0, fy: 600.0, cx: 320.0, cy: 240.0 };
//! let geometry = vec![
//!     CropGeometry { crop: CropBox { centre_x: 300.0, centre_y: 250.0, side: 90.0 }, intrinsics: camera, width: 640, height: 480 },
//!     CropGeometry { crop: CropBox { centre_x: 420.0, centre_y: 200.0, side: 60.0 }, intrinsics: camera, width: 640, height: 480 },
//! ];
//! let labels = vec![vec![Vector3::new(-30.0, 15.0, 700.0)], vec![Vector3::new(170.0, -70.0, 1050.0)]];
//! let space = TranslationSpace::from_labels(&labels, &geometry)?; // volume and scale, from labels
//! let model = TranslationPdf::new(TranslationConfig::small(32, space), Device::Cpu)?;
//! let options = TranslationTrainOptions { queries: 256, ..Default::default() };
//! let mut trainer = TranslationTrainer::new(model, options)?;
//! let images = Tensor::rand([2, 3, 32, 32], (Kind::Float, Device::Cpu));
//! assert!(trainer.train_step(&images, &geometry, &labels)?.loss.is_finite());
//!
//! let model = trainer.into_model();
//! let predictor = TranslationPredictor::new(&model);
//! let cells = predictor.refine_options(&geometry[0], 2.0); // the crop's volume in 2 mm cells
//! let distribution = predictor.hierarchical(&images.get(0), &geometry[0], &cells)?;
//! assert!((distribution.masses.iter().sum::<f64>() - 1.0).abs() < 1e-9);
//! # Ok::<(), ipdf_model::ModelError>(())
//! ```
mod augment;
mod checkpoint;
mod config;
mod crop;
mod cuda;
mod encoder;
mod encoding;
mod error;
mod fit;
mod head;
mod kernels;
mod layers;
mod loss;
mod network;
mod optim;
mod pretrained;
mod refine;
pub mod rotation;
mod step;
pub mod translation;

pub use augment::{Augmentation, augment};
pub use checkpoint::{CHECKPOINT_FILE, CheckpointInfo};
pub use config::ModelConfig;
pub use crop::{
    CropBox, CropOptions, ImageBox, crop_box, crop_in_box, crop_object, crops_to_tensor,
};
pub use cuda::{default_device, load_cuda_backend};
pub use encoder::EncoderKind;
pub use error::ModelError;
pub use fit::{EpochReport, FitOptions, FitTarget, TRAIN_LOG, fit};
pub use kernels::{REPRODUCIBLE_CPU_KERNELS, kernel_settings, missing_kernel_settings};
pub use optim::LearningRateSchedule;
pub use pretrained::{load_backbone, load_translation_backbone};
pub use refine::{
    CellHierarchy, CellMasses, HeaviestBall, RefineOptions, So3Cells, refine, refine_on,
};
pub use step::StepReport;
