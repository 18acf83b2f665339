//! BOP-format datasets (Hodaň et al., the BOP challenge layout), read and written by the same
//! code, so that the synthetic datasets of `ipdf synth` and real ones (T-LESS, YCB-V, … as
//! downloaded) load alike:
//!
//! ```text
//! DIR/models/obj_000001.ply            meshes in mm
//! DIR/models/models_info.json          diameter, extents, symmetries_discrete / _continuous
//! DIR/camera.json                      optional dataset-level camera
//! DIR/dataset_info.json                generator, variant, object names (ipdf synth only)
//! DIR/{split}/{scene_id:06}/scene_camera.json    cam_K, depth_scale per image id
//!                           scene_gt.json        cam_R_m2c, cam_t_m2c (mm), obj_id per instance
//!                           scene_gt_info.json   bbox_obj, bbox_visib, px_count_*, visib_fract
//!                           scene_pseudo_gt.json the pseudo labels of `ipdf label`
//!                           scene_reference_gt.json  the reference sets of `ipdf label --reference`
//!                           rgb/{im_id:06}.png|jpg  depth/{im_id:06}.png
//!                           mask/ and mask_visib/{im_id:06}_{inst:06}.png
//! ```
//!
//! - [`BopDataset`] and [`SceneDir`]: where each file lies; [`copy_dataset`] copies one.
//! - One reader and one writer per file: [`read_models_info`] / [`write_models_info`]
//!   ([`ModelInfo`] with its symmetry group), [`read_scene_camera`], [`read_scene_gt`],
//!   [`read_scene_gt_info`], [`read_pseudo_gt`] and their `write_*` twins, [`write_mesh_ply`].
//! - Images: [`read_depth`] (metres), [`read_mask`], [`read_rgb`] and their `write_*` twins.
//! - [`Progress`]: how the long jobs of the crates built on this one report their progress.
//! - [`write_atomically`] and [`write_json`]: every result file is written to a temporary sibling
//!   and renamed over its path, so a reader or a resumed run never sees half a file.
//!
//! Poses are model→camera `Isometry3<f64>` in metres; the files hold BOP's millimetres. Every
//! error names the file and the JSON key or image property at fault ([`FileError`]).
//!
//! ```
//! use std::collections::BTreeMap;
//! use bop_dataset::{BopDataset, GtInstance, read_scene_gt, write_scene_gt};
//! use nalgebra::{Isometry3, Vector3};
//!
//! let dir = tempfile::tempdir()?;
//! let dataset = BopDataset::new(dir.path());
//! let scene = dataset.scene("train", 0);
//! let pose = Isometry3::new(Vector3::new(0.01, -0.02, 0.7), Vector3::new(0.0, 0.5, 0.0));
//! let gt = BTreeMap::from([(0, vec![GtInstance { obj_id: 1, pose }])]);
//! write_scene_gt(&scene.gt_path(), &gt)?;
//! assert_eq!(dataset.scene_ids("train")?, vec![0]);
//! let back = read_scene_gt(&scene.gt_path())?;
//! assert!((back[&0][0].pose.translation.vector - pose.translation.vector).norm() < 1e-9);
//! // A damaged file is refused naming the file and the key.
//! std::fs::write(scene.gt_path(), r#"{"0": [{"obj_id": 1, "cam_t_m2c": [0, 0]}]}"#)?;
//! let error = read_scene_gt(&scene.gt_path()).unwrap_err();
//! assert_eq!(error.field, "0[0].cam_R_m2c");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
mod atomic;
mod dataset_info;
mod error;
mod images;
mod json;
mod layout;
mod models;
mod progress;
mod pseudo_gt;
mod recorded;
mod scene;

pub use atomic::{PARTIAL_SUFFIX, partial_path, write_atomically, write_json};
pub use dataset_info::DatasetInfo;
pub use error::FileError;
pub use images::{
    Image, image_file_complete, mask_box, read_depth, read_mask, read_rgb, write_depth, write_mask,
    write_rgb,
};
pub use json::{
    BopCamera, Intrinsics, camera_from_json, pose_from_json, pose_to_json, read_json, read_json_as,
};
pub use layout::{BopDataset, SceneDir, copy_dataset};
pub use models::{
    ModelInfo, mesh_appearance, read_models_info, write_coloured_mesh_ply, write_mesh_ply,
    write_models_info,
};
pub use progress::Progress;
pub use pseudo_gt::{PseudoInstance, PseudoLabel, read_pseudo_gt, write_pseudo_gt};
pub use recorded::{as_recorded, check_recorded};
pub use scene::{
    GtInfo, GtInstance, RotationRepairs, read_object_ids, read_scene_camera, read_scene_gt,
    read_scene_gt_info, read_scene_gt_repaired, write_scene_camera, write_scene_gt,
    write_scene_gt_info,
};
