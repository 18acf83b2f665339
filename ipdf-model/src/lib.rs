//! Implicit-PDF (Murphy et al., ICML 2021) on libtorch through `tch`: an image-conditioned,
//! unnormalised log-density `F(R, I)` over SO(3), trained on *sets* of rotation labels so that
//! it learns every orientation an object is indistinguishable under.
//!
//! - [`ImplicitPdf`]: an image encoder ([`EncoderKind`]: ResNet-18, ResNet-18 cut after stage
//!   3, ConvNeXt-Tiny, a small CNN; torchvision parameter names, [`load_backbone`] reads
//!   pretrained `.safetensors`), the positional encoding of the rotation query
//!   ([`encode_rotations`]) and the IPDF head. The image term is computed once per image and
//!   broadcast over all queries.
//! - [`Trainer`]: one step = a query set ([`QuerySampling`]: a rotated level-2 grid or uniform
//!   rotations) moved so that it holds a label exactly, a softmax over the queries, and the
//!   negative log-likelihood of the label set ([`LabelLoss`], [`set_nll`]) as a true density
//!   (cell volume `π² / N`). Adam with warm-up and cosine decay, gradient clipping, occlusion
//!   and colour augmentation ([`Augmentation`]); seeded. [`fit`] adds epochs, validation LLH,
//!   `train_log.csv` and checkpoints (`.safetensors` + JSON, atomic, resumable).
//! - [`Predictor`]: the normalised distribution on a grid level (chunked), hierarchical
//!   refinement ([`refine`]: level 2, then best-first only the cells holding the mass, within a
//!   query budget), `ln p(R | I)` at any rotation ([`Predictor::log_densities`], the
//!   reference's log-likelihood), a bfloat16 head for speed ([`Precision`]), and the most
//!   likely rotation by gradient ascent ([`Predictor::argmax`]).
//! - The translation half of a pose: [`TranslationPdf`] `F(t, I)` over the object's
//!   translation in the camera frame (mm), conditioned on the crop and where it was cut
//!   ([`CropGeometry`]: the crop's box and the camera intrinsics), queries in the crop's own
//!   coordinates, Fourier-encoded; a [`WorkingVolume`] set from the training labels, stored in the
//!   checkpoint, with an octree refined best-first as the rotation grid is ([`refine_on`] takes
//!   any [`CellHierarchy`]); [`TranslationTrainer`] (label sets, importance-sampled normaliser),
//!   [`TranslationPredictor`] (distribution, `ln p(t | I)`, argmax).
//!
//! ```
//! use ipdf_model::{ImplicitPdf, ModelConfig, Predictor, RefineOptions, TrainOptions, Trainer};
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
//! use ipdf_model::{
//!     CameraIntrinsics, CropBox, CropGeometry, TranslationConfig, TranslationPdf,
//!     TranslationPredictor, TranslationSpace, TranslationTrainOptions, TranslationTrainer,
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
mod crop;
mod cuda;
mod encoder;
mod encoding;
mod error;
mod fit;
mod head;
mod image_input;
mod kernels;
mod layers;
mod loss;
mod model;
mod optim;
mod predict;
mod pretrained;
mod refine;
mod train;
mod translation;

pub use augment::{Augmentation, augment};
pub use checkpoint::{CHECKPOINT_FILE, CheckpointInfo};
pub use crop::{CropOptions, crop_box, crop_object, crops_to_tensor};
pub use cuda::{default_device, load_cuda_backend};
pub use encoder::EncoderKind;
pub use encoding::{encode_rotations, encoded_len, rotations_to_tensor};
pub use error::ModelError;
pub use fit::{EpochReport, FitOptions, FitTarget, LabelledImages, TRAIN_LOG, fit, validation_llh};
pub use kernels::{REPRODUCIBLE_CPU_KERNELS, kernel_settings, missing_kernel_settings};
pub use loss::{LabelLoss, QuerySampling, label_set_from_matrices, set_nll};
pub use model::{ImplicitPdf, ModelConfig};
pub use optim::LearningRateSchedule;
pub use predict::{Argmax, ArgmaxOptions, Precision, Predictor, UNDER_RESOLUTION_LIMIT};
pub use pretrained::{load_backbone, load_translation_backbone};
pub use refine::{CellHierarchy, CellMasses, RefineOptions, So3Cells, refine, refine_on};
pub use train::{StepReport, TrainOptions, Trainer};
pub use translation::{
    CROP_VOLUME_SPAN, CameraIntrinsics, CropBox, CropGeometry, CropTerms, LabelledTranslations,
    MAX_OCTREE_LEVEL, TranslationArgmax, TranslationArgmaxOptions, TranslationConfig,
    TranslationPdf, TranslationPredictor, TranslationSpace, TranslationTrainOptions,
    TranslationTrainer, WorkingVolume, translation_validation_llh, translations_to_tensor,
};
