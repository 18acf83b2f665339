//! The libtorch-free libraries as another project uses them: `scripts/downstream-check.sh` puts
//! this file into a crate outside the workspace that depends on them by path, resolves that crate
//! afresh and runs it with the workspace's root as its argument. Public APIs only.
use std::error::Error;
use std::f64::consts::PI;
use std::path::Path;

use depth_render::{Material, PinholeCamera, TriangleMesh, load_mesh, sample_surface};
use ipdf_metrics::{Distribution, ModelPoints, add, llh};
use nalgebra::{Isometry3, Point3, Vector3};
use pseudo_label::{LabelOptions, ObjectModel, Observation, label_instance};
use rand::SeedableRng;
use registration::{PointCloud, PrepareOptions, RegisterOptions, prepare_cloud, register};
use so3_grid::{Grid, geodesic_distance};
use synth_data::{FrameRenderer, FrameStyle, ViewRange};

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// A real scan (metres), as users bring meshes: YCB's mustard bottle, 16,382 triangles.
const SCAN: &str = "depth-render/tests/data/ycb_006_mustard_bottle.ply";

fn main() -> Result<()> {
    let root = std::env::args()
        .nth(1)
        .ok_or("usage: downstream-check WORKSPACE_ROOT")?;
    let mesh = load_mesh(&Path::new(&root).join(SCAN), 1.0)?.mesh;
    let grid = check_grid()?;
    check_registration(&mesh)?;
    check_labelled_render(&mesh)?;
    check_metric(&grid)?;
    println!("downstream check: all passed");
    Ok(())
}

/// so3-grid: level 1 has 72·8 cells, each rotation in the cell its `locate` names.
fn check_grid() -> Result<Grid> {
    let grid = Grid::new(1)?;
    ensure(
        grid.len() == 576,
        format!("level-1 grid has {} cells", grid.len()),
    )?;
    let query = so3_grid::random_rotations(1, 3)[0];
    let (nearest, distance) = grid.nearest(&query)?;
    let centre = grid.rotations()[nearest as usize];
    ensure(
        (geodesic_distance(&centre, &query) - distance).abs() < 1e-9,
        "nearest cell",
    )?;
    println!("grid: level 1, {} cells", grid.len());
    Ok(grid)
}

/// registration: the scan's surface samples, moved by a rigid transform, are registered back.
fn check_registration(mesh: &TriangleMesh) -> Result<()> {
    let (points, _normals) = sample_surface(mesh, 8_000, 11);
    let truth = Isometry3::new(
        Vector3::new(0.03, -0.02, 0.05),
        Vector3::new(0.4, -0.3, 0.9),
    );
    let source = PointCloud::new(points)?;
    let target = source.transformed(&truth);
    let voxel = 0.005;
    let model = prepare_cloud(&source, &PrepareOptions::for_voxel(voxel))?;
    let observed = prepare_cloud(&target, &PrepareOptions::for_voxel(voxel))?;
    let options = RegisterOptions::for_voxel(voxel);
    let found = register(&model, &observed, &Isometry3::identity(), &options)?;
    let error = found.alignment.pose.inverse() * truth;
    let (metres, degrees) = (
        error.translation.vector.norm(),
        error.rotation.angle().to_degrees(),
    );
    println!("registration: error {:.2} mm, {degrees:.2}°", metres * 1e3);
    ensure(
        metres < 0.002 && degrees < 1.0,
        "registration missed the transform",
    )
}

/// synth-data renders the scan on a table (depth-render, parry3d's convex hull for its resting
/// pose), bop-dataset writes and reads the depth and mask PNGs, pseudo-label labels the view and
/// ipdf-metrics scores the best label against the rendered pose (ADD).
fn check_labelled_render(mesh: &TriangleMesh) -> Result<()> {
    let camera = PinholeCamera::new(1066.8, 1067.5, 312.99, 241.31, 640, 480)?;
    let style = FrameStyle::plain(Material::Uniform([0.9, 0.8, 0.1]));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let frame =
        FrameRenderer::new(mesh)?.render(&camera, &ViewRange::default(), &style, &mut rng)?;

    let dir = std::env::temp_dir().join(format!("downstream-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let (depth_path, mask_path) = (dir.join("depth.png"), dir.join("mask_visib.png"));
    let (width, height) = (camera.width, camera.height);
    bop_dataset::write_depth(&depth_path, &frame.depth, width, height, 0.1)?;
    bop_dataset::write_mask(&mask_path, &frame.mask_visib, width, height)?;
    let depth = bop_dataset::read_depth(&depth_path, 0.1)?.pixels;
    let mask = bop_dataset::read_mask(&mask_path)?.pixels;
    std::fs::remove_dir_all(&dir)?;

    let options = LabelOptions::default();
    let model = ObjectModel::new(1, mesh, &options)?;
    let observation = Observation::new(camera, &depth, &mask).ok_or("the scan is not in view")?;
    let labels = label_instance(&model, &observation, &options, 7).labels?;
    let samples: Vec<Point3<f64>> = mesh.positions().iter().map(|p| p.cast()).collect();
    let points = ModelPoints::new(&samples)?;
    let best = labels
        .iter()
        .map(|label| add(&points, &label.pose, &frame.pose))
        .fold(f64::INFINITY, f64::min);
    let diameter = points.diameter();
    println!(
        "labelled render: {} labels, best ADD {:.2} mm ({:.1} % of the {:.0} mm diameter)",
        labels.len(),
        best * 1e3,
        100.0 * best / diameter,
        diameter * 1e3
    );
    ensure(best < 0.02 * diameter, "no label near the rendered pose")
}

/// ipdf-metrics: a uniform density over SO(3) scores LLH = −ln π² at any rotation.
fn check_metric(grid: &Grid) -> Result<()> {
    let rotations = so3_grid::random_rotations(4, 9);
    let score = llh(&Distribution::uniform(grid), &rotations)?;
    println!(
        "metric: LLH of the uniform density {score:.4} (−ln π² = {:.4})",
        -(PI * PI).ln()
    );
    ensure((score + (PI * PI).ln()).abs() < 1e-9, "uniform LLH")
}

fn ensure(condition: bool, what: impl Into<String>) -> Result<()> {
    if condition {
        Ok(())
    } else {
        Err(what.into().into())
    }
}
