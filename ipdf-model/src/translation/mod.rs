//! The translation half of a 6D pose: an implicit density over the object's translation in the
//! camera frame, conditioned on the crop and on where the crop came from.
//!
//! - [`WorkingVolume`]: the box of translations (mm) the density lives in, with an octree of
//!   equal cells in Morton order for hierarchical evaluation ([`crate::refine_on`]).
//! - [`CropGeometry`]: the crop's square in the image ([`crate::CropBox`], from
//!   [`crate::crop_box`]) and the camera's intrinsics.
//! - [`TranslationPdf`]: `F(t, I)`; [`TranslationSpace`] (volume and query normalisation) is
//!   set from the training labels and kept in its configuration.
//! - [`TranslationTrainer`]: label sets of translations, each label in its own
//!   importance-sampled normaliser.
//! - [`TranslationPredictor`]: the distribution on the octree, `ln p(t | I)`, and the argmax.
//! - [`LabelledTranslations`]: training data for [`crate::fit`], validated by
//!   [`translation_validation_llh`].
//!
//! The same rooms as [`crate::rotation`]: `model`, `train`, `fit`, `predict`, `checkpoint`, and
//! the translation's own `geometry` (crops in the camera) and `volume` (the octree).
mod checkpoint;
mod fit;
mod geometry;
mod model;
mod predict;
mod train;
mod volume;

pub use fit::{LabelledTranslations, translation_validation_llh};
pub use geometry::{CameraIntrinsics, CropGeometry, translations_to_tensor};
pub use model::{
    CROP_VOLUME_SPAN, TranslationConfig, TranslationPdf, TranslationSpace, in_crop_span,
};
pub use predict::{CropTerms, TranslationArgmax, TranslationArgmaxOptions, TranslationPredictor};
pub use train::{TranslationTrainOptions, TranslationTrainer};
pub use volume::{MAX_OCTREE_LEVEL, WorkingVolume};
