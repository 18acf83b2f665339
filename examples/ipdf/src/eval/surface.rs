//! Whether a most likely rotation shows the camera what the truth shows: BOP's Visible Surface
//! Discrepancy (VSD) of the rotation placed where the truth is, against the frame's own depth
//! image. A pose whose VSD to the truth is under 0.3 is one the view cannot tell from the truth
//! (a box whose printed sides alone tell its half turns apart, a mug whose handle is hidden), so
//! a rotation within 15° of the truth's symmetries *or* under that VSD counts as a true pose.
//! Where the frame has depth, a most likely pose's translation fitted to it
//! ([`depth_fitted_translations`]) is scored beside the translation model's, and a pose found
//! from the rotation model's hypotheses and the depth ([`depth_refined_poses`]) beside the
//! models' own.
use std::collections::BTreeMap;
use std::collections::btree_map::Entry;

use std::path::PathBuf;

use bop_dataset::{
    BopDataset, FileError, Image, Intrinsics, read_depth, read_mask, read_scene_camera,
};
use depth_render::{
    Instance, PinholeCamera, Scene, SensorPreset, Window, unproject, visible_surface_discrepancy,
};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use pseudo_label::{LabelOptions, ObjectModel};

use crate::Error;
use crate::depth_fit::{fit_translation, median_point, pose_from_depth};
use crate::eval::object_mesh;
use crate::training_data::{Examples, InstanceRef, intrinsics_of};

/// BOP's visibility tolerance δ (metres).
pub const VSD_DELTA_M: f32 = 0.015;
/// BOP's misalignment tolerance τ (metres).
pub const VSD_TAU_M: f32 = 0.02;
/// BOP 2018 counts a pose correct under this VSD.
pub const VSD_CORRECT: f64 = 0.3;

/// Each instance's VSD between its rotation in `rotations` (its most likely one, or the
/// rotation of a pose refined with depth) and its ground-truth pose, judged against the depth
/// image of its frame in `split` of `dataset`, with object `obj_id`'s mesh. A rotation says
/// nothing of where the object is, so it is placed two ways and the lower VSD counts: the centre
/// of the mesh's bounding box where the truth puts it (a box turned half about its own centre
/// shows the surface the truth shows even where the mesh's origin is off that centre), and then
/// moved so that its rendered surface's median point (per axis) lies on the truth's: a mug's
/// bounding box is centred 8 mm off its axis, towards the handle, so a turn about the axis that
/// keeps the handle hidden moves the cup sideways about that centre. `None` for an instance
/// without a rotation, whose frame has no depth image, or where neither pose is visible.
pub fn rotation_vsd(
    dataset: &BopDataset,
    split: &str,
    obj_id: u32,
    examples: &Examples,
    rotations: &[Option<UnitQuaternion<f64>>],
) -> Result<Vec<Option<f64>>, Error> {
    let truths = examples.required_truth_poses()?;
    let mesh = object_mesh(dataset, obj_id, 0.001)?;
    let (low, high) = mesh.bounds();
    let centre = nalgebra::center(&low, &high).cast::<f64>();
    let scene_of_mesh = Scene::new(std::slice::from_ref(&mesh));
    let mut frames = FrameDepths::new(dataset, split);
    let mut scores = Vec::with_capacity(truths.len());
    for ((at, truth), rotation) in examples.instances.iter().zip(truths).zip(rotations) {
        let (Some(rotation), Some(frame)) = (rotation, frames.load(at)?) else {
            scores.push(None);
            continue;
        };
        let render = |pose: Isometry3<f64>| -> Result<Vec<f32>, Error> {
            let window = Window::full(&frame.camera);
            Ok(scene_of_mesh
                .render(&frame.camera, &[Instance::new(0, pose)], window)
                .map_err(|e| FileError::new(&frame.path, "render", e.to_string()))?
                .depth)
        };
        let truth = in_metres(truth);
        let at_centre = truth.transform_point(&centre) - rotation.transform_point(&centre);
        let centred = Isometry3::from_parts(at_centre.into(), *rotation);
        let truth_depth = render(truth)?;
        let centred_depth = render(centred)?;
        let vsd = |estimate_depth: &[f32]| {
            visible_surface_discrepancy(
                &frame.depth.pixels,
                estimate_depth,
                &truth_depth,
                VSD_DELTA_M,
                VSD_TAU_M,
            )
            .map(f64::from)
        };
        let mut score = vsd(&centred_depth);
        if let Some(aligned) = surface_aligned(&frame.camera, &truth_depth, &centred_depth, centred)
        {
            let aligned_score = vsd(&render(aligned)?);
            score = match (score, aligned_score) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
        }
        scores.push(score);
    }
    Ok(scores)
}

/// `pose`, whose rendered depth through `camera` is `depth`, moved so that the per-axis median
/// of its rendered surface's points lies on that of `reference_depth`'s; `None` where either
/// shows too few pixels ([`crate::depth_fit::MIN_PIXELS`]).
fn surface_aligned(
    camera: &PinholeCamera,
    reference_depth: &[f32],
    depth: &[f32],
    pose: Isometry3<f64>,
) -> Option<Isometry3<f64>> {
    let window = Window::full(camera);
    let median = |depth: &[f32]| median_point(&unproject(camera, window, depth, None));
    let shift = median(reference_depth)? - median(depth)?;
    Some(Isometry3::from_parts(
        (pose.translation.vector + shift).into(),
        pose.rotation,
    ))
}

/// Each instance's pose in `poses` (translation in mm) with its translation fitted to the
/// depth image of its frame in `split` of `dataset` inside the instance's visible mask
/// ([`crate::depth_fit::fit_translation`], object `obj_id`'s mesh), in mm. `None` for an
/// instance whose frame has no depth image or no mask, or too few readings in it.
pub fn depth_fitted_translations(
    dataset: &BopDataset,
    split: &str,
    obj_id: u32,
    examples: &Examples,
    poses: &[Isometry3<f64>],
) -> Result<Vec<Option<Vector3<f64>>>, Error> {
    let mesh = object_mesh(dataset, obj_id, 0.001)?;
    let scene_of_mesh = Scene::new(std::slice::from_ref(&mesh));
    let mut frames = FrameDepths::new(dataset, split);
    let mut fitted = Vec::with_capacity(poses.len());
    for (at, pose) in examples.instances.iter().zip(poses) {
        let Some((frame, mask)) = frames.load_masked(at)? else {
            fitted.push(None);
            continue;
        };
        let pose = fit_translation(
            &scene_of_mesh,
            &frame.camera,
            &frame.depth.pixels,
            &mask.pixels,
            &in_metres(pose),
        );
        fitted.push(pose.map(|p| p.translation.vector * 1000.0));
    }
    Ok(fitted)
}

/// Each instance's pose found from its rotation `hypotheses` (the most likely first) and the
/// depth image of its frame in `split` of `dataset` inside the instance's visible mask
/// ([`crate::depth_fit::pose_from_depth`] with the labeller's default options but `sensor`:
/// object `obj_id`'s mesh, the sensor's expected errors moved to the depth's noise, every other
/// pixel), translation in mm. `None` for an instance whose frame has no depth image or no mask,
/// or whose masked depth cannot be registered (too few points, another scale); `None` for the
/// whole split where no instance's frame has both (an RGB-only dataset, or boxes without masks):
/// there is nothing to refine against, which is not a failure to refine.
pub fn depth_refined_poses(
    dataset: &BopDataset,
    split: &str,
    obj_id: u32,
    examples: &Examples,
    hypotheses: &[Vec<UnitQuaternion<f64>>],
    sensor: SensorPreset,
) -> Result<Option<Vec<Option<Isometry3<f64>>>>, Error> {
    let options = LabelOptions {
        sensor,
        ..LabelOptions::default()
    };
    let model = ObjectModel::new(obj_id, &object_mesh(dataset, obj_id, 0.001)?, &options)?;
    let mut frames = FrameDepths::new(dataset, split);
    let mut refined = Vec::with_capacity(hypotheses.len());
    let mut any_depth = false;
    for (at, rotations) in examples.instances.iter().zip(hypotheses) {
        let Some((frame, mask)) = frames.load_masked(at)? else {
            refined.push(None);
            continue;
        };
        any_depth = true;
        let pose = pose_from_depth(
            &model,
            &options,
            &frame.camera,
            &frame.depth.pixels,
            &mask.pixels,
            rotations,
        );
        refined.push(pose.map(|found| {
            Isometry3::from_parts(
                (found.pose.translation.vector * 1000.0).into(),
                found.pose.rotation,
            )
        }));
    }
    Ok(any_depth.then_some(refined))
}

/// A pose whose translation is in mm, in metres.
fn in_metres(pose: &Isometry3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts((pose.translation.vector / 1000.0).into(), pose.rotation)
}

/// A frame's depth image (metres) and camera.
struct FrameDepth {
    depth: Image<f32>,
    camera: PinholeCamera,
    /// The depth image's file.
    path: PathBuf,
}

/// The depth images and cameras of a split's frames, each scene's `scene_camera.json` read once.
struct FrameDepths<'a> {
    dataset: &'a BopDataset,
    split: &'a str,
    cameras: BTreeMap<u32, BTreeMap<u32, Intrinsics>>,
}

impl<'a> FrameDepths<'a> {
    fn new(dataset: &'a BopDataset, split: &'a str) -> Self {
        Self {
            dataset,
            split,
            cameras: BTreeMap::new(),
        }
    }

    /// The depth image and camera of `at`'s frame with the instance's visible mask; `None`
    /// where the frame has no depth image or the instance no mask. A mask of another size than
    /// the depth image is an error naming it.
    fn load_masked(
        &mut self,
        at: &InstanceRef,
    ) -> Result<Option<(FrameDepth, Image<bool>)>, Error> {
        let mask_path = self
            .dataset
            .scene(self.split, at.scene_id)
            .visible_mask_path(at.im_id, at.instance);
        let frame = match self.load(at)? {
            Some(frame) if mask_path.exists() => frame,
            _ => return Ok(None),
        };
        let mask = read_mask(&mask_path)?;
        if (mask.width, mask.height) != (frame.depth.width, frame.depth.height) {
            let reason = format!(
                "{}×{} pixels, its depth image {}×{}",
                mask.width, mask.height, frame.depth.width, frame.depth.height
            );
            return Err(FileError::new(&mask_path, "size", reason).into());
        }
        Ok(Some((frame, mask)))
    }

    /// The depth image and camera of `at`'s frame; `None` where it has no depth image.
    fn load(&mut self, at: &InstanceRef) -> Result<Option<FrameDepth>, Error> {
        let scene = self.dataset.scene(self.split, at.scene_id);
        let path = scene.depth_path(at.im_id);
        if !path.exists() {
            return Ok(None);
        }
        let scene_cameras = match self.cameras.entry(at.scene_id) {
            Entry::Occupied(entry) => entry.into_mut(),
            Entry::Vacant(entry) => entry.insert(read_scene_camera(&scene.camera_path())?),
        };
        let intrinsics = intrinsics_of(scene_cameras, &scene, at.im_id)?;
        let depth = read_depth(&path, intrinsics.depth_scale)?;
        let camera = intrinsics
            .camera(depth.width, depth.height)
            .map_err(|e| FileError::new(&scene.camera_path(), at.im_id.to_string(), e.to_string()))?
            .camera;
        Ok(Some(FrameDepth {
            depth,
            camera,
            path,
        }))
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::f64::consts::{FRAC_PI_2, PI};

    use bop_dataset::{BopDataset, Intrinsics, write_depth, write_mesh_ply, write_scene_camera};
    use depth_render::primitives::{MugShape, cuboid, mug};
    use depth_render::{Instance, PinholeCamera, Scene, TriangleMesh, Window};
    use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector3};
    use tch::{Device, Kind, Tensor};

    use super::{in_metres, rotation_vsd, surface_aligned};
    use crate::training_data::{Examples, InstanceRef};

    /// A 10 × 6 × 4 cm box whose centre lies 3 cm and 2 cm off its mesh's origin, half a metre
    /// in front of a 160 × 120 camera, tilted so that three faces show; image 0 has its
    /// noise-free depth, image 1 none.
    fn box_dataset(root: &std::path::Path) -> (BopDataset, Isometry3<f64>) {
        let centred = cuboid([0.10, 0.06, 0.04]).unwrap();
        let offset = Vector3::new(0.03, 0.0, 0.02);
        let positions = centred.positions().iter().map(|p| p + offset).collect();
        let mesh = TriangleMesh::new(positions, centred.triangles().to_vec()).unwrap();
        let rotation = UnitQuaternion::from_euler_angles(0.5, -0.4, 0.3);
        dataset_of(root, &mesh, rotation, Vector3::new(0.01, -0.02, 0.5))
    }

    /// `mesh` as object 1 at `rotation` and `translation` (metres) before a 160 × 120 camera:
    /// image 0 has its noise-free depth, image 1 none. The ground truth in mm.
    fn dataset_of(
        root: &std::path::Path,
        mesh: &TriangleMesh,
        rotation: UnitQuaternion<f64>,
        translation: Vector3<f64>,
    ) -> (BopDataset, Isometry3<f64>) {
        let dataset = BopDataset::new(root);
        std::fs::create_dir_all(root.join("models")).unwrap();
        write_mesh_ply(&dataset.model_path(1), mesh).unwrap();
        let intrinsics = Intrinsics {
            fx: 200.0,
            fy: 200.0,
            cx: 80.0,
            cy: 60.0,
            depth_scale: 0.1,
        };
        let scene = dataset.scene("test", 0);
        std::fs::create_dir_all(scene.dir.join("depth")).unwrap();
        write_scene_camera(
            &scene.camera_path(),
            &BTreeMap::from([(0, intrinsics), (1, intrinsics)]),
        )
        .unwrap();
        let camera = camera();
        let metres = Isometry3::from_parts(translation.into(), rotation);
        let depth = Scene::new(std::slice::from_ref(mesh))
            .render(&camera, &[Instance::new(0, metres)], Window::full(&camera))
            .unwrap()
            .depth;
        write_depth(&scene.depth_path(0), &depth, 160, 120, 0.1).unwrap();
        let truth = Isometry3::from_parts((translation * 1000.0).into(), rotation);
        (dataset, truth)
    }

    fn camera() -> PinholeCamera {
        PinholeCamera::new(200.0, 200.0, 80.0, 60.0, 160, 120).unwrap()
    }

    /// A mug (8 cm across, 10 cm tall, its handle reaching 4 cm out on the mesh's +x side, so
    /// that its bounding box's centre lies 2 cm off its axis) 40 cm away, seen from the side and
    /// 10° above, its handle pointing away from the camera behind the cup.
    fn mug_dataset(root: &std::path::Path) -> (BopDataset, Isometry3<f64>, TriangleMesh) {
        let mesh = mug(&MugShape {
            radius: 0.04,
            height: 0.10,
            wall: 0.004,
            handle_reach: 0.035,
            handle_thickness: 0.01,
            segments: 48,
        })
        .unwrap();
        let (sin, cos) = 10f64.to_radians().sin_cos();
        // Columns: the mesh's x (the handle) away from the camera, its y to the left, its z
        // (the opening) up, each tilted by the 10° from above.
        let basis = Matrix3::new(0.0, -1.0, 0.0, -sin, 0.0, -cos, cos, 0.0, -sin);
        let rotation = UnitQuaternion::from_matrix(&basis);
        let (dataset, truth) = dataset_of(root, &mesh, rotation, Vector3::new(0.0, 0.0, 0.4));
        (dataset, truth, mesh)
    }

    fn examples(truth: Isometry3<f64>, images: &[u32]) -> Examples {
        Examples {
            crops: Tensor::zeros([images.len() as i64, 3, 8, 8], (Kind::Uint8, Device::Cpu)),
            label_sets: vec![vec![truth.rotation]; images.len()],
            translation_sets: vec![Vec::new(); images.len()],
            geometry: Vec::new(),
            truth_sets: None,
            truth_poses: Some(vec![truth; images.len()]),
            instances: images
                .iter()
                .map(|&im_id| InstanceRef {
                    scene_id: 0,
                    im_id,
                    instance: 0,
                })
                .collect(),
            visible_fractions: vec![None; images.len()],
            repairs: Default::default(),
            box_crops: 0,
        }
    }

    #[test]
    fn a_rotation_is_scored_by_the_surface_the_camera_sees() {
        let dir = tempfile::tempdir().unwrap();
        let (dataset, truth) = box_dataset(dir.path());
        let turned = |axis: Vector3<f64>, angle: f64| {
            truth.rotation * UnitQuaternion::from_scaled_axis(axis * angle)
        };
        let rotations = [
            truth.rotation,
            // A box shows the same surface turned half about an axis through its centre (the
            // rotation is placed about the centre, 3 cm and 2 cm from the mesh's origin).
            turned(Vector3::x(), PI),
            turned(Vector3::z(), PI),
            // A quarter turn about z swaps its 10 cm and 6 cm sides.
            turned(Vector3::z(), FRAC_PI_2),
        ];
        let scores: Vec<f64> = rotations
            .iter()
            .map(|r| {
                rotation_vsd(&dataset, "test", 1, &examples(truth, &[0]), &[Some(*r)]).unwrap()[0]
                    .unwrap()
            })
            .collect();
        assert!(scores[0] < 1e-3, "{scores:?}");
        assert!(scores[1] < 0.02 && scores[2] < 0.02, "{scores:?}");
        assert!(scores[3] > 0.3, "{scores:?}");
    }

    #[test]
    fn a_frame_without_depth_has_no_score() {
        let dir = tempfile::tempdir().unwrap();
        let (dataset, truth) = box_dataset(dir.path());
        let scores = rotation_vsd(
            &dataset,
            "test",
            1,
            &examples(truth, &[1, 0]),
            &[Some(truth.rotation), Some(truth.rotation)],
        )
        .unwrap();
        assert_eq!(scores[0], None);
        assert!(scores[1].is_some_and(|v| v < 1e-3), "{scores:?}");
    }

    #[test]
    fn a_frame_with_depth_but_no_camera_is_refused_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let (dataset, truth) = box_dataset(dir.path());
        let scene = dataset.scene("test", 0);
        std::fs::copy(scene.depth_path(0), scene.depth_path(2)).unwrap();
        let error = rotation_vsd(
            &dataset,
            "test",
            1,
            &examples(truth, &[2]),
            &[Some(truth.rotation)],
        )
        .unwrap_err()
        .to_string();
        assert!(
            error.contains("scene_camera.json") && error.contains("the image's intrinsics"),
            "{error}"
        );
    }

    /// A turn about a mug's axis that keeps its handle behind the cup shows the camera what
    /// the truth shows; placed by its bounding box's centre, 2 cm off the axis, the cup would
    /// stand 7 mm aside. Aligning the rendered surfaces' median points puts the turned mug back
    /// on the truth's axis, and its VSD is small; turned so that the handle faces the camera, it
    /// is not.
    #[test]
    fn a_turn_about_a_mugs_axis_with_its_handle_hidden_shows_what_the_truth_shows() {
        let dir = tempfile::tempdir().unwrap();
        let (dataset, truth, mesh) = mug_dataset(dir.path());
        let turned =
            |angle: f64| truth.rotation * UnitQuaternion::from_scaled_axis(Vector3::z() * angle);
        let rotation = turned(20f64.to_radians());
        // The oracle: the mesh's origin lies on the axis, so the turned mug at the truth's
        // translation is the truth's surface.
        let truth_metres = in_metres(&truth);
        let (low, high) = mesh.bounds();
        let centre = nalgebra::center(&low, &high).cast::<f64>();
        let centred = Isometry3::from_parts(
            (truth_metres.transform_point(&centre) - rotation.transform_point(&centre)).into(),
            rotation,
        );
        let aside = (centred.translation.vector - truth_metres.translation.vector).norm();
        assert!(aside > 0.006, "{aside}");
        let camera = camera();
        let scene = Scene::new(std::slice::from_ref(&mesh));
        let render = |pose: Isometry3<f64>| {
            scene
                .render(&camera, &[Instance::new(0, pose)], Window::full(&camera))
                .unwrap()
                .depth
        };
        let aligned =
            surface_aligned(&camera, &render(truth_metres), &render(centred), centred).unwrap();
        let off = (aligned.translation.vector - truth_metres.translation.vector).norm();
        assert!(off < 0.0015, "{off} m from the truth's translation");
        let vsd = |rotation: UnitQuaternion<f64>| {
            rotation_vsd(
                &dataset,
                "test",
                1,
                &examples(truth, &[0]),
                &[Some(rotation)],
            )
            .unwrap()[0]
                .unwrap()
        };
        assert!(vsd(rotation) < 0.1, "{}", vsd(rotation));
        // Lying on its side.
        let lying = truth.rotation * UnitQuaternion::from_scaled_axis(Vector3::x() * FRAC_PI_2);
        assert!(vsd(lying) > 0.3, "{}", vsd(lying));
    }
}
