//! The rotation half: Implicit-PDF over SO(3) (Murphy et al., ICML 2021).
//!
//! - [`ImplicitPdf`]: `F(R, I)`, an image encoder ([`crate::EncoderKind`]) and the positional
//!   encoding of the rotation query ([`encode_rotations`]) summed in the head. The image term
//!   is computed once per image and broadcast over all queries.
//! - [`Trainer`]: one step = a query set ([`QuerySampling`]: a rotated level-2 grid or uniform
//!   rotations) moved so that it holds a label exactly, a softmax over the queries, and the
//!   negative log-likelihood of the label set ([`LabelLoss`], [`set_nll`]) as a true density
//!   (cell volume `π² / N`).
//! - [`LabelledImages`]: training data for [`crate::fit`], validated by [`validation_llh`].
//! - [`Predictor`]: the normalised distribution on a grid level (chunked), hierarchical
//!   refinement ([`crate::refine`]), `ln p(R | I)` at any rotation
//!   ([`Predictor::log_densities`]), a bfloat16 head for speed ([`Precision`]), and the most
//!   likely rotation by gradient ascent ([`Predictor::argmax`]); its image term optionally
//!   averaged over test-time views of the crop ([`crop_views`], [`Predictor::with_views`]);
//!   the same for an ensemble of models, whose `F` is the mean of theirs
//!   ([`Predictor::ensemble`], stored as a checkpoint whose [`ENSEMBLE_FILE`] names the other
//!   members: [`ImplicitPdf::load_ensemble`], [`write_ensemble`]).
//! - [`RotationFrame`]: the camera's frame, or the line of sight's through the crop's centre,
//!   in which one look of the object is one rotation wherever in the image it was cut.
//!
//! The same rooms as [`crate::translation`]: `model`, `train`, `fit`, `predict`, `checkpoint`,
//! and the rotation's own `loss` (query sets over SO(3)).
mod checkpoint;
mod fit;
mod frame;
mod loss;
mod model;
mod predict;
mod train;
mod views;

pub use crate::encoding::{encode_rotations, rotations_to_tensor};
pub use checkpoint::{ENSEMBLE_FILE, write_ensemble};
pub use fit::{LabelledImages, validation_llh};
pub use frame::RotationFrame;
pub use loss::{LabelLoss, QuerySampling, label_set_from_matrices, set_nll};
pub use model::ImplicitPdf;
pub use predict::{Argmax, ArgmaxOptions, Precision, Predictor, UNDER_RESOLUTION_LIMIT};
pub use train::{TrainOptions, Trainer};
pub use views::{MAX_EXTRA_VIEWS, VIEW_SHIFT, crop_views};
