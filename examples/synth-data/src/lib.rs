//! Synthetic RGB-D datasets in BOP format (`ipdf synth`): each frame shows one object resting
//! on a tabletop in a physically plausible pose (a stable face of its convex hull, random yaw
//! and position), seen by a camera at a random elevation (15–80°) and distance (0.5–1.0 m),
//! optionally with distractors that occlude it, a depth sensor's errors and a detector's mask errors. Faithful
//! geometry, not photorealism. Two variants, as in the paper: `uniform` (one flat colour per
//! object) and `texture` (a mesh file's own texture or vertex colours, else model-space colour
//! patches that break the visual symmetry but not the geometric one). [`Randomization`] draws
//! each frame's look at random (lights, procedural table and background textures, textured
//! distractors, a colour camera's image chain) for models that must read real images.
//!
//! Frames are rendered in parallel; frame `i` of scene `s` draws from ChaCha8 stream
//! `s · 2³² + i` of the seed, so a dataset is the same at any thread count. A scene is complete
//! once its `scene_gt_info.json` exists (written last), and a rerun skips complete scenes. The
//! options that decide a split's frames are recorded in its `synth_options.json` (written before
//! the first frame), and a rerun with other options is refused rather than mixed in.
//!
//! - [`synthesize`] writes a split of a [`bop_dataset::BopDataset`] from [`SynthObject`]s
//!   ([`ObjectKind`] built-ins with their analytic symmetry groups, or mesh files) and
//!   [`SynthOptions`]; [`FrameRenderer`] renders single frames.
//! - [`trials`]: partial views of a non-symmetric object with their true poses, the data of the
//!   registration benchmarks.
//!
//! ```
//! use bop_dataset::{BopDataset, read_scene_gt};
//! use synth_data::{ObjectKind, SynthObject, SynthOptions, synthesize};
//!
//! let dir = tempfile::tempdir()?;
//! let dataset = BopDataset::new(dir.path());
//! let can = SynthObject::built_in(ObjectKind::Can)?;
//! let options = SynthOptions { frames: 2, ..SynthOptions::default() };
//! // `&()`: no progress shown (the `ipdf` CLI passes a progress bar).
//! let summary = synthesize(&dataset, "train", &[can], &options, &())?;
//! assert_eq!((summary.frames, summary.rendered, summary.scenes), (2, 2, 1));
//! let gt = read_scene_gt(&dataset.scene("train", 0).gt_path())?;
//! assert_eq!(gt.len(), 2);
//! // The same options again: the scene is complete and nothing is rendered.
//! let again = synthesize(&dataset, "train", &[SynthObject::built_in(ObjectKind::Can)?], &options, &())?;
//! assert_eq!(again.rendered, 0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
mod error;
mod frame;
mod objects;
mod procedural;
mod randomize;
mod synthesize;
pub mod trials;

pub use error::SynthError;
pub use frame::{
    FIRM_TIPPING_DEG, Frame, FrameRenderer, FrameStyle, LEANING_DEG, LEANING_SHARE, Placement,
    ViewRange,
};
pub use objects::{ObjectKind, SynthObject};
pub use randomize::Randomization;
pub use synthesize::{SYNTH_OPTIONS_FILE, SynthOptions, SynthSummary, Variant, synthesize};
