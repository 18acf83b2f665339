//! A small split written by [`synth_data::synthesize`] and read back with `bop-dataset`'s
//! readers, checked against what the scene must look like: the object rendered again alone at
//! the written pose covers exactly the written mask, and its depth is the written depth; every
//! frame is there once; the same seed writes the same bytes at any thread count.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use bop_dataset::{
    BopDataset, Progress, read_depth, read_mask, read_models_info, read_scene_camera,
    read_scene_gt, read_scene_gt_info,
};
use depth_render::{Instance, Scene, Window};
use nalgebra::Point3;
use synth_data::{ObjectKind, SynthObject, SynthOptions, synthesize};

/// The objects of the split: the cracker box (convex, so that its centroid projects inside
/// its silhouette) and the can.
const OBJECTS: [ObjectKind; 2] = [ObjectKind::Box, ObjectKind::Can];

/// 3 frames per object, 2 per scene: scenes 0 and 1 the box's (frames 0–1, then 2), 2 and 3
/// the can's. Clean depth, exact masks, nothing else on the table.
fn options(seed: u64) -> SynthOptions {
    SynthOptions {
        frames: 3,
        frames_per_scene: 2,
        seed,
        ..SynthOptions::default()
    }
}

fn objects() -> Vec<SynthObject> {
    OBJECTS
        .into_iter()
        .map(|kind| SynthObject::built_in(kind).unwrap())
        .collect()
}

/// Records what a job reports.
#[derive(Default)]
struct Recorded {
    total: Mutex<Option<(u64, u64)>>,
    advanced: Mutex<u64>,
}

impl Progress for Recorded {
    fn set_total(&self, total: u64, done: u64) {
        *self.total.lock().unwrap() = Some((total, done));
    }

    fn advance(&self, units: u64) {
        *self.advanced.lock().unwrap() += units;
    }
}

/// Every file under `root`, by path relative to it, with its bytes.
fn files(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut found = BTreeMap::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                found.insert(path.strip_prefix(root).unwrap().to_path_buf(), bytes);
            }
        }
    }
    found
}

/// The pixels set in a row-major mask `width` wide: `[x, y, w, h]` of their bounding box, as
/// BOP's `bbox_obj` (the BOP toolkit's `calc_2d_bbox`: `w` is the last column minus the first).
fn bounding_box(mask: &[bool], width: usize) -> [i64; 4] {
    let (mut low, mut high) = ([usize::MAX; 2], [0; 2]);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        let (u, v) = (i % width, i / width);
        low = [low[0].min(u), low[1].min(v)];
        high = [high[0].max(u), high[1].max(v)];
    }
    [low[0], low[1], high[0] - low[0], high[1] - low[1]].map(|x| x as i64)
}

#[test]
fn each_frame_shows_the_object_at_its_written_pose() {
    let dir = tempfile::tempdir().unwrap();
    let dataset = BopDataset::new(dir.path());
    let objects = objects();
    let progress = Recorded::default();
    let summary = synthesize(&dataset, "train", &objects, &options(7), &progress).unwrap();
    assert_eq!(
        (summary.frames, summary.rendered, summary.scenes),
        (6, 6, 4)
    );
    assert_eq!(*progress.total.lock().unwrap(), Some((6, 0)));
    assert_eq!(*progress.advanced.lock().unwrap(), 6);
    assert_eq!(dataset.scene_ids("train").unwrap(), [0, 1, 2, 3]);
    // The box's diameter is its space diagonal: 60 × 158 × 210 mm.
    let models = read_models_info(&dataset.models_info_path()).unwrap();
    let diagonal = (60f64.powi(2) + 158f64.powi(2) + 210f64.powi(2)).sqrt();
    assert!(
        (models[&1].diameter - diagonal).abs() < 0.01,
        "{}",
        models[&1].diameter
    );
    let mut frames = 0;
    for (scene_id, (k, frame_ids)) in [(0, [0, 1].as_slice()), (1, &[0]), (2, &[0, 1]), (3, &[0])]
        .into_iter()
        .map(|(scene, ids)| (scene, (scene as usize / 2, ids)))
    {
        let scene = dataset.scene("train", scene_id);
        let gt = read_scene_gt(&scene.gt_path()).unwrap();
        let info = read_scene_gt_info(&scene.gt_info_path()).unwrap();
        let cameras = read_scene_camera(&scene.camera_path()).unwrap();
        assert_eq!(gt.keys().copied().collect::<Vec<_>>(), frame_ids);
        assert_eq!(cameras.len(), frame_ids.len());
        let mesh = &objects[k].mesh;
        let alone = Scene::new(std::slice::from_ref(mesh));
        // The model's centroid: the mean of its vertices (the box's centre).
        let centroid = Point3::from(
            mesh.positions()
                .iter()
                .map(|p| p.coords.cast::<f64>())
                .sum::<nalgebra::Vector3<f64>>()
                / mesh.positions().len() as f64,
        );
        for &im_id in frame_ids {
            frames += 1;
            let [instance] = gt[&im_id].as_slice() else {
                panic!("one instance per frame: {:?}", gt[&im_id]);
            };
            assert_eq!(instance.obj_id as usize, k + 1);
            let intrinsics = cameras[&im_id];
            let mask = read_mask(&scene.mask_path(im_id, 0)).unwrap();
            let visible = read_mask(&scene.mask_visib_path(im_id, 0)).unwrap();
            let depth = read_depth(&scene.depth_path(im_id), intrinsics.depth_scale).unwrap();
            let camera = intrinsics.camera(mask.width, mask.height).unwrap().camera;
            let width = camera.width as usize;
            // Rendered again alone at the written pose: the silhouette is the mask, pixel for
            // pixel, and nothing stands in front of any of it.
            let rendering = alone
                .render(
                    &camera,
                    &[Instance::new(0, instance.pose)],
                    Window::full(&camera),
                )
                .unwrap();
            let silhouette: Vec<bool> = rendering.instance.iter().map(Option::is_some).collect();
            assert!(silhouette == mask.pixels, "scene {scene_id} image {im_id}");
            assert!(
                visible.pixels == mask.pixels,
                "scene {scene_id} image {im_id}"
            );
            // Clean depth: the object's own depth on every pixel of it (to the PNG's 0.1 mm).
            for (i, _) in mask.pixels.iter().enumerate().filter(|(_, m)| **m) {
                let (read, rendered) = (depth.pixels[i], rendering.depth[i]);
                assert!(
                    (read - rendered).abs() < 1e-4,
                    "pixel {i}: {read} {rendered}"
                );
            }
            // Its boxes and counts are those of the masks.
            let pixels = mask.pixels.iter().filter(|m| **m).count() as u64;
            let with_depth = mask
                .pixels
                .iter()
                .zip(&depth.pixels)
                .filter(|(m, d)| **m && **d > 0.0)
                .count() as u64;
            let info = info[&im_id][0];
            assert!(pixels > 1000, "{pixels}");
            assert_eq!(
                (info.px_count_all, info.px_count_valid, info.px_count_visib),
                (pixels, with_depth, pixels)
            );
            assert_eq!(info.visib_fract, 1.0);
            assert_eq!(info.bbox_obj, bounding_box(&mask.pixels, width));
            assert_eq!(info.bbox_visib, info.bbox_obj);
            // The centroid projects inside the box and, the object being convex, onto it.
            let pixel = camera.project(&(instance.pose * centroid)).unwrap();
            let [x, y, w, h] = info.bbox_obj.map(|v| v as f64);
            assert!((x..x + w).contains(&pixel.x) && (y..y + h).contains(&pixel.y));
            let (u, v) = (pixel.x as usize, pixel.y as usize);
            assert!(mask.pixels[v * width + u], "{pixel}");
        }
    }
    assert_eq!(frames, 6);
    // Run again: every scene is complete, nothing is rendered, and the progress is all there.
    let again = Recorded::default();
    let summary = synthesize(&dataset, "train", &objects, &options(7), &again).unwrap();
    assert_eq!((summary.rendered, summary.repaired), (0, 0));
    assert_eq!(*again.advanced.lock().unwrap(), 6);
}

#[test]
fn a_seed_writes_the_same_bytes_at_any_thread_count_and_another_seed_other_frames() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, seed: u64, threads: usize| {
        let root = dir.path().join(name);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            synthesize(
                &BopDataset::new(&root),
                "train",
                &objects(),
                &options(seed),
                &(),
            )
        })
        .unwrap();
        files(&root)
    };
    let first = write("first", 7, 1);
    let again = write("again", 7, 3);
    // Models, camera, dataset info, options, and per scene 3 JSON files and per frame
    // rgb, depth, mask and mask_visib.
    assert_eq!(first.len(), 2 + 1 + 1 + 1 + 1 + 4 * 3 + 6 * 4);
    assert_eq!(
        first.keys().collect::<Vec<_>>(),
        again.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &first {
        assert!(*bytes == again[path], "{} differs", path.display());
    }
    let other = write("other", 8, 1);
    assert_eq!(
        first.keys().collect::<Vec<_>>(),
        other.keys().collect::<Vec<_>>()
    );
    for (path, bytes) in &first {
        let name = path.to_string_lossy();
        if name.contains("depth/") || name.ends_with("scene_gt.json") {
            assert!(
                *bytes != other[path],
                "{name} is the same for seeds 7 and 8"
            );
        }
    }
}

/// A 100 mm cube as an ASCII PLY, every vertex at texture coordinates (0.5, 0.5), with the
/// `header` lines (a comment) and, where `colour` is given (`r g b`), that vertex colour.
fn cube_ply(header: &str, colour: &str) -> String {
    let mut ply = format!(
        "ply\nformat ascii 1.0\n{header}element vertex 8\nproperty float x\nproperty float y\n\
         property float z\nproperty float texture_u\nproperty float texture_v\n"
    );
    if !colour.is_empty() {
        ply += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    ply += "element face 6\nproperty list uchar int vertex_indices\nend_header\n";
    for k in 0..8 {
        let [x, y, z] = [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b| b as f64 * 100.0 - 50.0);
        ply += &format!("{x} {y} {z} 0.5 0.5 {colour}\n");
    }
    // The six faces, each a quad turning outwards.
    ply + "4 0 2 3 1\n4 4 5 7 6\n4 0 1 5 4\n4 2 6 7 3\n4 0 4 6 2\n4 1 3 7 5\n"
}

/// The colours of the object's visible pixels in every frame of `variant` of `object`, the
/// frames' look drawn as `randomization` says.
fn object_pixels(
    object: &SynthObject,
    variant: synth_data::Variant,
    randomization: synth_data::Randomization,
) -> Vec<[u8; 3]> {
    let dir = tempfile::tempdir().unwrap();
    let dataset = BopDataset::new(dir.path());
    let options = SynthOptions {
        frames: 2,
        frames_per_scene: 2,
        variant,
        randomization,
        ..SynthOptions::default()
    };
    let objects = std::slice::from_ref(object);
    synthesize(&dataset, "train", objects, &options, &Recorded::default()).unwrap();
    let scene = dataset.scene("train", 0);
    let mut pixels = Vec::new();
    for im_id in [0, 1] {
        let rgb = bop_dataset::read_rgb(&scene.rgb_path(im_id)).unwrap();
        let mask = read_mask(&scene.mask_visib_path(im_id, 0)).unwrap();
        pixels.extend(
            rgb.pixels
                .iter()
                .zip(&mask.pixels)
                .filter(|(_, m)| **m)
                .map(|(p, _)| *p),
        );
    }
    assert!(pixels.len() > 100, "{} object pixels", pixels.len());
    pixels
}

#[test]
fn a_mesh_files_own_texture_or_vertex_colours_show_in_the_texture_variant() {
    use synth_data::{Randomization, Variant};
    let dir = tempfile::tempdir().unwrap();
    // A texture of one colour, pure green: every shaded pixel of the cube is green, darker or
    // lighter, and nothing else; the uniform variant shows it grey.
    let texture = vec![[0u8, 200, 0]; 16];
    bop_dataset::write_rgb(&dir.path().join("green.png"), &texture, 4, 4).unwrap();
    let textured = dir.path().join("textured.ply");
    std::fs::write(&textured, cube_ply("comment TextureFile green.png\n", "")).unwrap();
    let (object, _) = SynthObject::from_mesh_file(&textured, 0.001).unwrap();
    let green = object_pixels(&object, Variant::Texture, Randomization::NONE);
    assert!(
        green.iter().all(|&[r, g, b]| r == 0 && b == 0 && g > 0),
        "{green:?}"
    );
    let grey = object_pixels(&object, Variant::Uniform, Randomization::NONE);
    assert!(
        grey.iter().all(|&[r, g, b]| r == g && g == b && r > 0),
        "{grey:?}"
    );

    // Vertex colours (red) where the file names no texture.
    let coloured = dir.path().join("coloured.ply");
    std::fs::write(&coloured, cube_ply("", "255 0 0")).unwrap();
    let (object, _) = SynthObject::from_mesh_file(&coloured, 0.001).unwrap();
    let red = object_pixels(&object, Variant::Texture, Randomization::NONE);
    assert!(
        red.iter().all(|&[r, g, b]| r > 0 && g == 0 && b == 0),
        "{red:?}"
    );

    // A texture the file names but that is not there: refused, naming the mesh and the field.
    let missing = dir.path().join("missing.ply");
    std::fs::write(&missing, cube_ply("comment TextureFile gone.png\n", "")).unwrap();
    let error = SynthObject::from_mesh_file(&missing, 0.001)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("missing.ply")
            && error.contains("TextureFile")
            && error.contains("gone.png"),
        "{error}"
    );
}

#[test]
fn a_mesh_without_a_surface_of_its_own_wears_a_random_one_when_textures_are_randomised() {
    use synth_data::{Randomization, Variant};
    let dir = tempfile::tempdir().unwrap();
    let textures = Randomization {
        textures: true,
        ..Randomization::NONE
    };
    // No texture, no vertex colours: the texture variant's colour patches in the plain look; with
    // textures randomised the same frames (the geometry is drawn before the look: the same
    // visible pixels) show it in other colours.
    let bare = dir.path().join("bare.ply");
    std::fs::write(&bare, cube_ply("", "")).unwrap();
    let (object, _) = SynthObject::from_mesh_file(&bare, 0.001).unwrap();
    let patches = object_pixels(&object, Variant::Texture, Randomization::NONE);
    let drawn = object_pixels(&object, Variant::Texture, textures);
    assert_eq!(patches.len(), drawn.len());
    assert!(patches != drawn);
    // A mesh with its own colours keeps them: the object's pixels are those of the plain look.
    let coloured = dir.path().join("coloured.ply");
    std::fs::write(&coloured, cube_ply("", "255 0 0")).unwrap();
    let (object, _) = SynthObject::from_mesh_file(&coloured, 0.001).unwrap();
    assert_eq!(
        object_pixels(&object, Variant::Texture, textures),
        object_pixels(&object, Variant::Texture, Randomization::NONE)
    );
}

#[test]
fn randomised_looks_keep_the_scenes_and_are_reproducible() {
    use synth_data::Randomization;
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, randomization, threads| {
        let root = dir.path().join(name);
        let options = SynthOptions {
            randomization,
            ..options(7)
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| synthesize(&BopDataset::new(&root), "train", &objects(), &options, &()))
            .unwrap();
        files(&root)
    };
    let plain = write("plain", Randomization::NONE, 1);
    let random = write("random", Randomization::ALL, 1);
    // Seeded: the same bytes at another thread count.
    assert!(random == write("again", Randomization::ALL, 3));
    let options = &random[Path::new("train/synth_options.json")];
    let options: serde_json::Value = serde_json::from_slice(options).unwrap();
    assert_eq!(
        options["randomize"],
        serde_json::json!(["lights", "backgrounds", "textures", "camera"])
    );
    // The look is drawn after the geometry: poses, boxes, masks and (clean) depth are the
    // plain split's; the colour images are not.
    for (path, bytes) in &plain {
        let name = path.to_string_lossy();
        if name.contains("rgb/") {
            assert!(*bytes != random[path], "{name} is the plain image");
        } else if name.starts_with("train/0") {
            assert!(*bytes == random[path], "{name} differs");
        }
    }
    // Around the object, the plain frames show a flat-shaded table and a black background
    // (a few colours); the randomised ones textures, lights and noise.
    let colours_around = |root: &str, im_id: u32| {
        let scene = BopDataset::new(&dir.path().join(root)).scene("train", 0);
        let rgb = bop_dataset::read_rgb(&scene.rgb_path(im_id))
            .unwrap()
            .pixels;
        let mask = read_mask(&scene.mask_path(im_id, 0)).unwrap().pixels;
        let around: std::collections::BTreeSet<[u8; 3]> = rgb
            .iter()
            .zip(&mask)
            .filter(|p| !*p.1)
            .map(|p| *p.0)
            .collect();
        around.len()
    };
    for im_id in [0, 1] {
        assert!(
            colours_around("plain", im_id) <= 3,
            "{}",
            colours_around("plain", im_id)
        );
        assert!(colours_around("random", im_id) > 100);
    }
}

/// The dataset's model keeps the mesh file's colours, so that the labeller can tell apart by
/// colour the poses that depth cannot: a texture image is written beside it with the source's
/// texels and named by the model, vertex colours are written in it.
#[test]
fn the_written_model_keeps_the_mesh_files_texture_and_vertex_colours() {
    use depth_render::{Material, load_mesh};
    let dir = tempfile::tempdir().unwrap();
    let texels: Vec<[u8; 3]> = (0..16u8).map(|i| [10 * i, 200, 255 - 7 * i]).collect();
    bop_dataset::write_rgb(&dir.path().join("pattern.png"), &texels, 4, 4).unwrap();
    let textured = dir.path().join("textured.ply");
    std::fs::write(&textured, cube_ply("comment TextureFile pattern.png\n", "")).unwrap();
    let coloured = dir.path().join("coloured.ply");
    std::fs::write(&coloured, cube_ply("", "255 0 0")).unwrap();
    for (name, source) in [("textured", &textured), ("coloured", &coloured)] {
        let (object, _) = SynthObject::from_mesh_file(source, 0.001).unwrap();
        let dataset = BopDataset::new(&dir.path().join(name));
        let options = SynthOptions {
            frames: 1,
            frames_per_scene: 1,
            ..SynthOptions::default()
        };
        let objects = std::slice::from_ref(&object);
        synthesize(&dataset, "train", objects, &options, &Recorded::default()).unwrap();
        let model = dataset.model_path(1);
        let loaded = load_mesh(&model, 0.001).unwrap();
        match bop_dataset::mesh_appearance(&model, &loaded).unwrap() {
            Some(Material::Image(texture)) if name == "textured" => {
                assert_eq!(texture.size(), (4, 4));
                assert_eq!(texture.to_rgb8(), texels);
            }
            Some(Material::VertexColors) if name == "coloured" => {
                let colours = loaded.mesh.colors().unwrap();
                assert!(colours.iter().all(|&c| c == [1.0, 0.0, 0.0]), "{colours:?}");
            }
            other => panic!("{name}: {other:?}"),
        }
    }
}
