//! Split a split of mug views by whether the camera sees the handle: each view is rendered at
//! its ground-truth pose (every object of the image, so others occlude it) and the pixels whose
//! nearest surface is the mug's handle are counted. The mug is `ipdf synth`'s (the cup centred
//! on the z axis, the handle towards +x); the handle is every face whose centre lies farther
//! from that axis than the cup's wall, read on the side opposite the handle. Views showing none of it go
//! to the split `<SPLIT>_handle_hidden`, the others to `<SPLIT>_handle_visible` (BOP layout,
//! files copied), to be labelled (`ipdf label --reference`) and scored (`ipdf eval --truth
//! reference`) apart. This is how docs/results.md picks the views a mug's model must spread
//! its mass along an arc on: by what the camera sees, not by what the depth sensor returned.
//!
//! ```text
//! cargo run --release -p ipdf --example mug_handle_views -- DATASET SPLIT [OBJ_ID]
//! ```
use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use bop_dataset::{BopDataset, read_json, read_scene_camera, read_scene_gt};
use depth_render::{Instance, Scene, TriangleMesh, Window, load_mesh};

/// The faces of a mug's mesh (metres, axis z, the cup centred on it) that form its handle.
fn handle_faces(mesh: &TriangleMesh) -> Vec<bool> {
    let radius = -mesh
        .positions()
        .iter()
        .map(|p| p.x)
        .fold(f32::INFINITY, f32::min);
    (0..mesh.triangles().len())
        .map(|i| {
            let c = mesh.corners(i);
            let (x, y) = (
                (c[0].x + c[1].x + c[2].x) / 3.0,
                (c[0].y + c[1].y + c[2].y) / 3.0,
            );
            x.hypot(y) > 1.01 * radius
        })
        .collect()
}

/// Copies the entries of `ids` of every `scene_*.json` and their images from `from` to `to`.
fn copy_views(from: &Path, to: &Path, ids: &BTreeSet<u32>) -> Result<()> {
    fs::create_dir_all(to)?;
    for entry in fs::read_dir(from)? {
        let path = entry?.path();
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        if path.is_dir() {
            let target = to.join(name);
            fs::create_dir_all(&target)?;
            for image in fs::read_dir(&path)? {
                let image = image?.path();
                let stem = image
                    .file_name()
                    .and_then(|n| n.to_str())
                    .unwrap_or_default();
                let id = stem.split(['_', '.']).next().and_then(|s| s.parse().ok());
                if id.is_some_and(|id| ids.contains(&id)) {
                    fs::copy(&image, target.join(stem))?;
                }
            }
        } else if name.starts_with("scene_") && name.ends_with(".json") {
            let value = read_json(&path)?;
            let kept: serde_json::Map<_, _> = value
                .as_object()
                .with_context(|| format!("{}: not a JSON object", path.display()))?
                .iter()
                .filter(|(k, _)| k.parse().is_ok_and(|id: u32| ids.contains(&id)))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect();
            fs::write(to.join(name), serde_json::to_string(&kept)?)?;
        }
    }
    Ok(())
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(root), Some(split)) = (args.first(), args.get(1)) else {
        bail!("usage: mug_handle_views DATASET SPLIT [OBJ_ID]");
    };
    let mug_id: u32 = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let dataset = BopDataset::new(Path::new(root));
    let mut scenes = Vec::new();
    let mut obj_ids = BTreeSet::from([mug_id]);
    for scene_id in dataset.scene_ids(split)? {
        let scene_dir = dataset.scene(split, scene_id);
        let gt = read_scene_gt(&scene_dir.gt_path())?;
        obj_ids.extend(gt.values().flatten().map(|g| g.obj_id));
        scenes.push((scene_dir, gt));
    }
    let mesh_of: BTreeMap<u32, usize> =
        obj_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    let meshes = obj_ids
        .iter()
        .map(|&id| Ok(load_mesh(&dataset.model_path(id), 1e-3)?.mesh))
        .collect::<Result<Vec<_>>>()?;
    let handle = handle_faces(&meshes[mesh_of[&mug_id]]);
    let renderer = Scene::new(&meshes);
    let mut chosen: BTreeMap<(u32, bool), BTreeSet<u32>> = BTreeMap::new();
    for (scene_dir, gt) in &scenes {
        let cameras = read_scene_camera(&scene_dir.camera_path())?;
        for (&im_id, instances) in gt {
            let Some(k) = instances.iter().position(|g| g.obj_id == mug_id) else {
                continue;
            };
            let intrinsics = cameras
                .get(&im_id)
                .with_context(|| format!("scene_camera.json: no entry {im_id}"))?;
            let (width, height) = image::image_dimensions(scene_dir.rgb_path(im_id))?;
            let camera = intrinsics.camera(width, height)?.camera;
            let placed: Vec<Instance> = instances
                .iter()
                .map(|g| Instance::new(mesh_of[&g.obj_id], g.pose))
                .collect();
            let rendering = renderer.render(&camera, &placed, Window::full(&camera))?;
            let on_mug: Vec<usize> = (0..rendering.depth.len())
                .filter(|&i| rendering.instance[i] == Some(k as u16))
                .collect();
            let on_handle = on_mug
                .iter()
                .filter(|&&i| handle[rendering.triangle[i] as usize])
                .count();
            println!(
                "scene {} image {im_id}: {on_handle} of {} pixels on the handle",
                scene_dir.id,
                on_mug.len()
            );
            chosen
                .entry((scene_dir.id, on_handle == 0))
                .or_default()
                .insert(im_id);
        }
    }
    for ((scene_id, hidden), ids) in &chosen {
        let name = format!(
            "{split}_handle_{}",
            if *hidden { "hidden" } else { "visible" }
        );
        let from = dataset.scene(split, *scene_id).dir;
        let to: PathBuf = Path::new(root).join(&name).join(format!("{scene_id:06}"));
        copy_views(&from, &to, ids)?;
        println!("{name}/{scene_id:06}: {} views", ids.len());
    }
    Ok(())
}
