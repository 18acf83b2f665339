//! BOP-format datasets (Hodaň et al., the BOP challenge layout), read and written by the same
//! code, so that the synthetic datasets of `ipdf synth` and real ones (T-LESS, YCB-V, … as
//! downloaded) load alike:
//!
//! ```text
//! DIR/models/obj_000001.ply            meshes in mm
//! DIR/models/models_info.json          diameter, extents, symmetries_discrete / _continuous
//! DIR/camera.json                      optional dataset-level camera
//! DIR/{split}/{scene_id:06}/scene_camera.json    cam_K, depth_scale per image id
//!                           scene_gt.json        cam_R_m2c, cam_t_m2c (mm), obj_id per instance
//!                           scene_gt_info.json   bbox_obj, bbox_visib, px_count_*, visib_fract
//!                           scene_pseudo_gt.json the pseudo labels of `ipdf label`
//!                           rgb/{im_id:06}.png|jpg  depth/{im_id:06}.png
//!                           mask/ and mask_visib/{im_id:06}_{inst:06}.png
//! ```
//!
//! Every error names the file and the JSON key or image property at fault ([`FileError`]).
mod models;
mod pseudo_gt;
mod scene;

use std::path::{Path, PathBuf};

pub use models::{ModelInfo, read_models_info, write_mesh_ply, write_models_info};
pub use pseudo_gt::{PseudoInstance, PseudoLabel, read_pseudo_gt, write_pseudo_gt};
pub use scene::{
    GtInfo, GtInstance, read_object_ids, read_scene_camera, read_scene_gt, read_scene_gt_info,
    write_scene_camera, write_scene_gt, write_scene_gt_info,
};

use crate::FileError;

/// A BOP dataset folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BopDataset {
    /// The dataset's root folder.
    pub root: PathBuf,
    /// The folder of `obj_NNNNNN.ply` and `models_info.json` (`models` unless chosen otherwise,
    /// e.g. T-LESS's `models_cad`).
    pub models: PathBuf,
}

impl BopDataset {
    /// The dataset at `root`, its meshes in `root/models`. Nothing is read yet.
    pub fn new(root: &Path) -> Self {
        Self {
            root: root.to_path_buf(),
            models: root.join("models"),
        }
    }

    /// The dataset at `root` with meshes in `root/models_dir`; fails when `root` is not a folder.
    pub fn open(root: &Path, models_dir: &str) -> Result<Self, FileError> {
        if !root.is_dir() {
            return Err(FileError::new(root, "folder", "not a dataset folder"));
        }
        Ok(Self {
            root: root.to_path_buf(),
            models: root.join(models_dir),
        })
    }

    /// `models/models_info.json`.
    pub fn models_info_path(&self) -> PathBuf {
        self.models.join("models_info.json")
    }

    /// The mesh of object `obj_id`: `models/obj_NNNNNN.ply`.
    pub fn model_path(&self, obj_id: u32) -> PathBuf {
        self.models.join(format!("obj_{obj_id:06}.ply"))
    }

    /// The scene ids of `split` (its six-digit subfolders), sorted. A missing split is an error
    /// naming the folder.
    pub fn scene_ids(&self, split: &str) -> Result<Vec<u32>, FileError> {
        let dir = self.root.join(split);
        let entries = std::fs::read_dir(&dir)
            .map_err(|e| FileError::new(&dir, "folder", format!("split {split:?}: {e}")))?;
        let mut ids = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| FileError::new(&dir, "folder", e.to_string()))?;
            let name = entry.file_name();
            let name = name.to_string_lossy();
            if entry.path().is_dir()
                && name.len() == 6
                && let Ok(id) = name.parse::<u32>()
            {
                ids.push(id);
            }
        }
        ids.sort_unstable();
        Ok(ids)
    }

    /// Scene `scene_id` of `split` (it need not exist yet).
    pub fn scene(&self, split: &str, scene_id: u32) -> SceneDir {
        SceneDir {
            dir: self.root.join(split).join(format!("{scene_id:06}")),
            id: scene_id,
        }
    }
}

/// One scene folder of a split.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneDir {
    /// `DIR/{split}/{scene_id:06}`.
    pub dir: PathBuf,
    /// The scene id.
    pub id: u32,
}

impl SceneDir {
    /// `scene_camera.json`.
    pub fn camera_path(&self) -> PathBuf {
        self.dir.join("scene_camera.json")
    }

    /// `scene_gt.json`.
    pub fn gt_path(&self) -> PathBuf {
        self.dir.join("scene_gt.json")
    }

    /// `scene_gt_info.json`.
    pub fn gt_info_path(&self) -> PathBuf {
        self.dir.join("scene_gt_info.json")
    }

    /// `scene_pseudo_gt.json`, beside `scene_gt.json`.
    pub fn pseudo_gt_path(&self) -> PathBuf {
        self.dir.join("scene_pseudo_gt.json")
    }

    /// The colour image: `rgb/{im_id:06}.png`, or `.jpg` when only that exists.
    pub fn rgb_path(&self, im_id: u32) -> PathBuf {
        let png = self.dir.join("rgb").join(format!("{im_id:06}.png"));
        let jpg = png.with_extension("jpg");
        if !png.exists() && jpg.exists() {
            jpg
        } else {
            png
        }
    }

    /// `depth/{im_id:06}.png`.
    pub fn depth_path(&self, im_id: u32) -> PathBuf {
        self.dir.join("depth").join(format!("{im_id:06}.png"))
    }

    /// The full silhouette of instance `instance`: `mask/{im_id:06}_{instance:06}.png`.
    pub fn mask_path(&self, im_id: u32, instance: usize) -> PathBuf {
        self.dir
            .join("mask")
            .join(format!("{im_id:06}_{instance:06}.png"))
    }

    /// The mask of instance `instance`'s visible part, `mask_visib/{im_id:06}_{instance:06}.png`,
    /// or, in a dataset without a `mask_visib` folder, its full silhouette from `mask/`.
    pub fn visible_mask_path(&self, im_id: u32, instance: usize) -> PathBuf {
        let visible = self.mask_visib_path(im_id, instance);
        let full = self.mask_path(im_id, instance);
        if !self.dir.join("mask_visib").is_dir() && full.exists() {
            full
        } else {
            visible
        }
    }

    /// The visible part of instance `instance`: `mask_visib/{im_id:06}_{instance:06}.png`.
    pub fn mask_visib_path(&self, im_id: u32, instance: usize) -> PathBuf {
        self.dir
            .join("mask_visib")
            .join(format!("{im_id:06}_{instance:06}.png"))
    }
}
