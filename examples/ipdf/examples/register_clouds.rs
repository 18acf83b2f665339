//! Register two clouds: a lumpy egg's model against one rendered, noisy partial view of it
//! (FPFH + Fast Global Registration + ICP), and how far the pose found is from the truth.
//!
//! ```text
//! cargo run --release -p ipdf --example register_clouds
//! ```
use anyhow::Result;
use nalgebra::{Isometry3, Point3};
use registration::{NormalOrientation, PrepareOptions, RegisterOptions, prepare_cloud, register};
use synth_data::trials::{egg_mesh, model_cloud, registration_trials};

fn main() -> Result<()> {
    let mesh = egg_mesh()?;
    let model = model_cloud(&mesh, 40_000, 0)?; // surface samples with normals
    let view = registration_trials(&mesh, 1, 7)?.remove(0);
    let voxel = 0.005;
    let options = PrepareOptions::for_voxel(voxel);
    // Once per model: downsample, normals propagated over the surface, FPFH, k-d tree.
    let source = prepare_cloud(
        &model,
        &options.oriented(NormalOrientation::Consistent { neighbours: 10 }),
    )?;
    // Per view: normals face the camera at the origin.
    let target = prepare_cloud(
        &view.view,
        &options.oriented(NormalOrientation::TowardsViewpoint(Point3::origin())),
    )?;
    let found = register(
        &source,
        &target,
        &Isometry3::identity(),
        &RegisterOptions::for_voxel(voxel),
    )?;
    let error = found.alignment.pose.inverse() * view.truth;
    println!(
        "{} model and {} view points: {:.2}° and {:.1} mm from the true pose, fitness {:.2}, {:.0} ms",
        source.cloud.len(),
        target.cloud.len(),
        error.rotation.angle().to_degrees(),
        error.translation.vector.norm() * 1e3,
        found.alignment.fitness,
        (found.fgr_time + found.icp_time).as_secs_f64() * 1e3
    );
    Ok(())
}
