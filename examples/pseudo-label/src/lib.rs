//! Pseudo ground-truth pose labels from RGB-D images and a mesh, with no annotation
//! (`ipdf label`), with no libtorch: for every object instance of every image, the masked depth becomes a point
//! cloud that is registered to the model (random P0 → FPFH + FGR → ICP) and validated by
//! rendering the model at the pose found and comparing depths. The best of several trials,
//! checked against the poses it is most often mistaken for, is one label; the instance's pseudo-GT set holds up to `labels` of them, spread over the
//! object's symmetries (see [`symmetries`] for why and how), poses scoring worse than a
//! threshold dropped and near-duplicates merged.
//!
//! [`label_dataset`] runs over a BOP split: parallel over images (a sample of each scene's
//! first, which sets each object's early stop: see `LabelOptions::good_score`), one
//! `scene_pseudo_gt.json` per scene written atomically, finished scenes skipped on a rerun,
//! `--shard i/n` for job arrays. Ground-truth poses are never read: from `scene_gt.json` only
//! each instance's `obj_id` (or `obj_id` given for datasets without it). An instance that cannot
//! be labelled gets an `"error"` and the run goes on; [`report`] scores labels against the
//! ground truth where there is one.
//!
//! ```
//! use depth_render::{DepthSensor, MaskErrors, Material};
//! use pseudo_label::{LabelOptions, ObjectModel, Observation, label_instance};
//! use synth_data::{FrameRenderer, FrameStyle, ObjectKind, SynthObject, SynthOptions, ViewRange};
//! use rand::SeedableRng;
//!
//! // One frame of the cracker box as a Kinect sees it, with a detector's mask (in a dataset:
//! // its depth and mask_visib PNGs).
//! let object = SynthObject::built_in(ObjectKind::Box)?;
//! let camera = SynthOptions::t_less_camera().camera;
//! let style = FrameStyle {
//!     sensor: Some(DepthSensor::kinect()),
//!     mask_errors: Some(MaskErrors::default()),
//!     ..FrameStyle::plain(Material::Uniform(object.colour))
//! };
//! let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
//! let frame = FrameRenderer::new(&object.mesh)?.render(&camera, &ViewRange::default(), &style, &mut rng)?;
//!
//! let options = LabelOptions::default();
//! let model = ObjectModel::new(1, &object.mesh, &options)?; // once per object
//! let observation = Observation::new(camera, &frame.depth, &frame.mask_visib).expect("visible");
//! let labels = label_instance(&model, &observation, &options, 7).labels.expect("labelled");
//! // A box with three different edges looks the same in 4 orientations: one label for each.
//! assert_eq!(labels.len(), 4);
//! for label in &labels {
//!     let error = object.symmetry.class_distances(&frame.pose.rotation, &label.pose.rotation);
//!     assert!(error.iter().fold(f64::INFINITY, |a, &b| a.min(b)).to_degrees() < 1.0);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
mod appearance;
mod arc;
mod dataset;
mod early_stop;
mod error;
mod instance;
mod model;
mod placement;
mod reference;
mod report;
mod score;
mod seeded;
pub mod symmetries;

pub use appearance::{MIN_APPEARANCE_MATCH, appearance_keeps, appearance_match};
pub use dataset::{
    APPEARANCE_MARGIN, APPEARANCE_MARGINS, DatasetOptions, LABEL_OPTIONS_FILE, LabelOptions,
    LabelSummary, REFERENCE_OPTIONS_FILE, Shard, Strategy, label_dataset, reference_dataset,
};
pub use error::LabelError;
pub use instance::{
    InstanceLabels, LabelFailure, align_from, extent_warning, global_alignment, initial_pose,
    label_instance, noise_ratio, observed_cloud, observed_features,
};
pub use model::ObjectModel;
pub use placement::{compare_in, refine_pose, score_pose};
pub use reference::{ReferenceOptions, ReferenceSet, reference_set};
pub use report::{
    COVERAGE_ANGLE_DEG, InstanceAgainstReference, LabelReport, ObjectLabelScores, VISIBILITY_BINS,
    VisibilityBin, report,
};
pub use score::{Comparison, Observation, PixelLattice, compare_pose, render_and_compare};
pub use seeded::{SeededPose, pose_from_hypotheses};
