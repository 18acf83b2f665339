//! The folder layout of a BOP dataset: where each file of a split and scene lies.
use std::path::{Path, PathBuf};

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

    /// The dataset-level `camera.json`.
    pub fn camera_path(&self) -> PathBuf {
        self.root.join("camera.json")
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

    /// The images of `split`: the entries of every scene's `scene_camera.json` (scenes without
    /// one count none).
    pub fn image_count(&self, split: &str) -> Result<usize, FileError> {
        let mut count = 0;
        for scene_id in self.scene_ids(split)? {
            let path = self.scene(split, scene_id).camera_path();
            if path.exists() {
                count += crate::read_scene_camera(&path)?.len();
            }
        }
        Ok(count)
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
