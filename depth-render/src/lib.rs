//! CPU ray casting of triangle meshes into depth images and instance masks.
//!
//! - [`TriangleMesh`]: validated vertices and faces (metres, model frame); [`load_mesh`]
//!   reads PLY and OBJ files; [`primitives`] builds closed, outward-wound shapes with exact
//!   dimensions.
//! - [`PinholeCamera`]: OpenCV intrinsics; depth is z-depth.
//! - [`Scene`]: one obvhs compressed-wide BVH per mesh, instanced by model→camera poses and
//!   rendered row-parallel into a [`Rendering`] of any pixel [`Window`].
//! - [`unproject`] depth back to points, [`depth_discrepancy`] (the render-and-compare score),
//!   [`DepthNoise`] (a sensor model), [`sample_surface`] (area-weighted points and normals).
//!
//! ```
//! use depth_render::{primitives, Instance, PinholeCamera, Scene, Window};
//! use nalgebra::{Isometry3, Vector3};
//!
//! let cube = primitives::cuboid([0.1, 0.1, 0.1])?;
//! let camera = PinholeCamera::new(500.0, 500.0, 32.0, 24.0, 64, 48)?;
//! let scene = Scene::new(&[cube]);
//! let pose = Isometry3::translation(0.0, 0.0, 0.5);
//! let out = scene.render(&camera, &[Instance::new(0, pose)], Window::full(&camera))?;
//! // The principal ray meets the cube's front face at z = 0.5 − 0.05.
//! let centre = (24 * 64 + 32) as usize;
//! assert!((out.depth[centre] - 0.45).abs() < 1e-6);
//! # Ok::<(), depth_render::RenderError>(())
//! ```

mod camera;
mod compare;
mod error;
mod mesh;
mod mesh_io;
mod noise;
pub mod primitives;
mod render;
mod resting;
mod sampling;
mod shading;
mod surface;
mod symmetry;
mod tile_cast;

pub use camera::PinholeCamera;
pub use compare::{depth_discrepancy, unproject};
pub use error::RenderError;
pub use mesh::TriangleMesh;
pub use mesh_io::load_mesh;
pub use noise::DepthNoise;
pub use render::{Instance, NO_TRIANGLE, Rendering, Scene, Window};
pub use resting::{RestingPose, group_by_symmetry, resting_poses};
pub use sampling::sample_surface;
pub use shading::{ImageTexture, Lighting, Material};
pub use symmetry::Primitive;
