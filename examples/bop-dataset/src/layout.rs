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
        if !root.exists() {
            return Err(FileError::new(root, "folder", "does not exist"));
        }
        if !root.is_dir() {
            return Err(FileError::new(
                root,
                "folder",
                "is a file, not a dataset folder",
            ));
        }
        let dataset = Self {
            root: root.to_path_buf(),
            models: root.join(models_dir),
        };
        dataset.check_models()?;
        Ok(dataset)
    }

    /// Fails when the models folder is missing, naming the folders of the dataset that hold a
    /// `models_info.json` (T-LESS ships `models_cad`, `models_eval` and `models_reconst`).
    pub fn check_models(&self) -> Result<(), FileError> {
        if self.models.is_dir() {
            return Ok(());
        }
        let mut candidates: Vec<String> = std::fs::read_dir(&self.root)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|entry| entry.path().join("models_info.json").is_file())
            .map(|entry| entry.file_name().to_string_lossy().into_owned())
            .collect();
        candidates.sort();
        let hint = match candidates.as_slice() {
            [] => "no folder of the dataset holds a models_info.json".to_string(),
            [one] => format!("choose {one} with --models-dir {one}"),
            many => format!("choose one of {} with --models-dir", many.join(", ")),
        };
        Err(FileError::new(
            &self.models,
            "folder",
            format!("missing: the object meshes and models_info.json are needed; {hint}"),
        ))
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
    /// naming the folder and the splits that exist.
    pub fn scene_ids(&self, split: &str) -> Result<Vec<u32>, FileError> {
        let dir = self.root.join(split);
        if !dir.is_dir() {
            let splits = self.splits();
            let known = if splits.is_empty() {
                "the dataset has no split (a folder of six-digit scene folders)".to_string()
            } else {
                format!("the dataset's splits: {}", splits.join(", "))
            };
            return Err(FileError::new(
                &dir,
                "folder",
                format!("split {split:?} does not exist; {known}"),
            ));
        }
        let entries =
            std::fs::read_dir(&dir).map_err(|e| FileError::new(&dir, "folder", e.to_string()))?;
        let mut ids = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| FileError::new(&dir, "folder", e.to_string()))?;
            ids.extend(scene_folder_id(&entry));
        }
        ids.sort_unstable();
        Ok(ids)
    }

    /// The splits of the dataset: its subfolders that hold a scene folder (six digits), sorted.
    pub fn splits(&self) -> Vec<String> {
        let Ok(entries) = std::fs::read_dir(&self.root) else {
            return Vec::new();
        };
        let mut splits: Vec<String> = entries
            .flatten()
            .filter(|entry| {
                std::fs::read_dir(entry.path()).is_ok_and(|mut scenes| {
                    scenes.any(|scene| scene.is_ok_and(|s| scene_folder_id(&s).is_some()))
                })
            })
            .map(|entry| entry.file_name().to_string_lossy().into_owned())
            .collect();
        splits.sort();
        splits
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

/// Copies the dataset folder `from` (every file and folder below it) into `to`, creating it:
/// labelling writes into a dataset, so a read-only one (or a test fixture) is labelled in a
/// copy. An error names the file or folder that could not be read or written.
pub fn copy_dataset(from: &Path, to: &Path) -> Result<(), FileError> {
    let failed = |path: &Path, what: &str, error: std::io::Error| {
        FileError::new(path, what, format!("cannot copy: {error}"))
    };
    std::fs::create_dir_all(to).map_err(|e| failed(to, "folder", e))?;
    for entry in std::fs::read_dir(from).map_err(|e| failed(from, "folder", e))? {
        let entry = entry.map_err(|e| failed(from, "folder", e))?;
        let (source, target) = (entry.path(), to.join(entry.file_name()));
        if source.is_dir() {
            copy_dataset(&source, &target)?;
        } else {
            std::fs::copy(&source, &target).map_err(|e| failed(&source, "file", e))?;
        }
    }
    Ok(())
}

/// The scene id of a split's entry: a folder named by six digits (`000001`).
fn scene_folder_id(entry: &std::fs::DirEntry) -> Option<u32> {
    let name = entry.file_name();
    let name = name.to_str()?;
    if name.len() == 6 && entry.path().is_dir() {
        name.parse().ok()
    } else {
        None
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

    /// `scene_reference_gt.json`, beside `scene_gt.json`: the reference sets of `ipdf label
    /// --reference`, in the format of `scene_pseudo_gt.json`.
    pub fn reference_gt_path(&self) -> PathBuf {
        self.dir.join("scene_reference_gt.json")
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

    /// Whether the scene has a folder of masks that [`SceneDir::visible_mask_path`] reads:
    /// `mask_visib/`, or `mask/`.
    pub fn has_masks(&self) -> bool {
        self.dir.join("mask_visib").is_dir() || self.dir.join("mask").is_dir()
    }

    /// The visible part of instance `instance`: `mask_visib/{im_id:06}_{instance:06}.png`.
    pub fn mask_visib_path(&self, im_id: u32, instance: usize) -> PathBuf {
        self.dir
            .join("mask_visib")
            .join(format!("{im_id:06}_{instance:06}.png"))
    }
}
