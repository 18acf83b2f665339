//! Each label's colour match (`pseudo_label::appearance_match`) beside its angle to the ground
//! truth, for a labelled split of a BOP dataset with colour images: what
//! `ipdf label --appearance-margin` is chosen from on data of your own. Labels made with the
//! colours off (`--appearance-margin 0`) show every look-alike.
//!
//! ```sh
//! cargo run --release -p pseudo-label --example label_colours -- DATASET SPLIT OBJ_ID [MESH] [LIMIT]
//! ```
//!
//! One line per labelled instance of object `OBJ_ID`: scene, image, instance, its visible
//! pixels on the labeller's lattice, then `angle:match` per label (degrees to the ground-truth
//! rotation; `none` where no match can be computed). `MESH` (a textured PLY in mm) replaces the
//! dataset's model, `LIMIT` (default 400) caps the instances. Last, for a few margins, the
//! share of the labels within 5° of the truth and of the others that the margin would drop.
use std::error::Error;
use std::path::{Path, PathBuf};

use bop_dataset::{
    BopDataset, GtInstance, PseudoLabel, mesh_appearance, read_depth, read_mask, read_pseudo_gt,
    read_rgb, read_scene_camera, read_scene_gt,
};
use pseudo_label::{
    LabelOptions, ObjectModel, Observation, PixelLattice, appearance_keeps, appearance_match,
};

/// Each label's angle to the truth (degrees) and its match, per instance.
type Matched = Vec<Vec<(f64, Option<f64>)>>;

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dataset, split, obj_id, rest @ ..] = args.as_slice() else {
        return Err("usage: label_colours DATASET SPLIT OBJ_ID [MESH] [LIMIT]".into());
    };
    let dataset = BopDataset::open(Path::new(dataset), "models")?;
    let obj_id: u32 = obj_id.parse()?;
    let mesh_path = rest
        .first()
        .map_or_else(|| dataset.model_path(obj_id), PathBuf::from);
    let limit: usize = rest.get(1).map_or(Ok(400), |l| l.parse())?;
    let loaded = depth_render::load_mesh(&mesh_path, 0.001)?;
    let appearance = mesh_appearance(&mesh_path, &loaded)?
        .ok_or("the mesh has neither a texture nor vertex colours")?;
    let options = LabelOptions::default();
    let model = ObjectModel::new(obj_id, &loaded.mesh, &options)?.with_appearance(Some(appearance));
    let mut matched: Matched = Vec::new();
    'scenes: for scene_id in dataset.scene_ids(split)? {
        let scene = dataset.scene(split, scene_id);
        let cameras = read_scene_camera(&scene.camera_path())?;
        let truth = read_scene_gt(&scene.gt_path())?;
        for (im_id, instances) in read_pseudo_gt(&scene.pseudo_gt_path())? {
            let intrinsics = cameras.get(&im_id).ok_or("an image without a camera")?;
            let depth = read_depth(&scene.depth_path(im_id), intrinsics.depth_scale)?;
            let rgb = read_rgb(&scene.rgb_path(im_id))?;
            let camera = intrinsics.camera(depth.width, depth.height)?.camera;
            let lattice = PixelLattice::new(&camera, options.pixel_stride);
            let depth = lattice.sample(&depth.pixels, 0.0);
            let colour = lattice.sample(&rgb.pixels, [0; 3]);
            for (k, instance) in instances.iter().enumerate() {
                if instance.obj_id != obj_id || instance.labels.is_empty() {
                    continue;
                }
                let truth = truth
                    .get(&im_id)
                    .and_then(|t| t.get(k))
                    .ok_or("an instance without ground truth")?;
                let mask = lattice.sample(
                    &read_mask(&scene.visible_mask_path(im_id, k))?.pixels,
                    false,
                );
                let Some(observation) = Observation::new(lattice.camera, &depth, &mask) else {
                    continue;
                };
                let observation = observation.with_colour(&colour);
                let labels = matched_labels(&model, &observation, &instance.labels, truth);
                let shown: Vec<String> = labels
                    .iter()
                    .map(|(angle, m)| {
                        format!(
                            "{angle:.1}:{}",
                            m.map_or("none".into(), |m| format!("{m:.3}"))
                        )
                    })
                    .collect();
                let visible = mask.iter().filter(|&&m| m).count();
                println!("{scene_id} {im_id} {k} {visible} {}", shown.join(" "));
                matched.push(labels);
                if matched.len() >= limit {
                    break 'scenes;
                }
            }
        }
    }
    for margin in [0.1, 0.15, 0.2, 0.3] {
        let [true_dropped, true_labels, others_dropped, others] = dropped(&matched, margin);
        eprintln!(
            "margin {margin}: drops {true_dropped} of {true_labels} labels within 5° of the truth, \
             {others_dropped} of {others} others"
        );
    }
    Ok(())
}

/// Each of `labels`' angle to the ground truth `truth` (degrees) and its colour match.
fn matched_labels(
    model: &ObjectModel,
    observation: &Observation,
    labels: &[PseudoLabel],
    truth: &GtInstance,
) -> Vec<(f64, Option<f64>)> {
    labels
        .iter()
        .map(|label| {
            let angle = label.pose.rotation.angle_to(&truth.pose.rotation);
            let matched = appearance_match(model, observation, &label.pose);
            (angle.to_degrees(), matched)
        })
        .collect()
}

/// Labels within 5° of the truth dropped, such labels, other labels dropped, other labels: by
/// the labeller's rule with `margin` ([`appearance_keeps`]).
fn dropped(matched: &Matched, margin: f64) -> [usize; 4] {
    let mut counts = [0; 4];
    for labels in matched {
        let matches: Vec<Option<f64>> = labels.iter().map(|l| l.1).collect();
        for (&(angle, _), kept) in labels.iter().zip(appearance_keeps(&matches, margin)) {
            let k = if angle < 5.0 { 0 } else { 2 };
            counts[k] += usize::from(!kept);
            counts[k + 1] += 1;
        }
    }
    counts
}
