//! CPU ray casting of triangle meshes into depth, instance masks, triangle ids, normals and
//! shaded RGB.
//!
//! - [`TriangleMesh`]: validated vertices and faces (metres, model frame) with optional vertex
//!   normals, colours and texture coordinates; [`load_mesh`] reads PLY and OBJ files,
//!   [`load_vertices`] their vertices alone (point clouds) and [`write_ply`] writes PLY;
//!   [`primitives`] builds closed, outward-wound shapes with exact dimensions and [`Primitive`]
//!   names them with their analytic symmetries ([`ShapeSymmetry`]).
//! - [`resting_poses`]: the faces of the convex hull an object can stand on, with their
//!   probabilities; [`RestingPose::on_table`] places it on a table.
//! - [`PinholeCamera`]: OpenCV intrinsics; depth is z-depth.
//! - [`Scene`]: one BVH per mesh (obvhs' PLOC builder), instanced by model→camera poses and
//!   rendered over any pixel [`Window`] by casting the rays of 16×16-pixel tiles together:
//!   front-to-back frustum traversal and an exact, watertight ray–triangle test. Then
//!   [`Scene::normals`], [`Scene::barycentrics`] and [`Scene::shade`] (ambient + Lambert + a
//!   Blinn–Phong highlight under a coloured light, [`Lighting`]; [`Material`]: flat colour,
//!   vertex colours, image texture at the mesh's coordinates or projected, or
//!   symmetry-breaking patches).
//! - [`unproject`] depth back to points, [`depth_discrepancy`] (the render-and-compare score),
//!   [`visible_surface_discrepancy`] (BOP's VSD of two poses), [`sample_surface`]
//!   (area-weighted points and normals).
//! - [`DepthSensor`]: what a real depth camera reads of a clean rendering (axial and lateral
//!   noise, quantisation, shadows, dropped pixels, misregistration), with presets for
//!   structured light and active stereo ([`SensorPreset`]); [`ImageChain`]: what a colour
//!   camera makes of a shaded image (blur, gains, noise, tone curve, JPEG); [`MaskErrors`]: a
//!   detector's imprecise masks.
//!
//! ```
//! use depth_render::{Instance, Lighting, Material, PinholeCamera, Primitive, Scene, Window};
//! use nalgebra::{Isometry3, Vector3};
//!
//! let can = Primitive::Cylinder { radius: 0.04, height: 0.1, segments: 64 };
//! let camera = PinholeCamera::new(500.0, 500.0, 32.0, 24.0, 64, 48)?;
//! let scene = Scene::new(&[can.mesh()?]);
//! // The can's axis along the camera's z-axis, its bottom cap 0.45 m away.
//! let instances = [Instance::new(0, Isometry3::translation(0.0, 0.0, 0.5))];
//! let out = scene.render(&camera, &instances, Window::full(&camera))?;
//! let centre = 24 * 64 + 32;
//! assert!((out.depth[centre] - 0.45).abs() < 1e-6);
//! // The cap's outward normal faces the camera.
//! let normals = scene.normals(&camera, &instances, &out)?;
//! assert!((Vector3::from(normals[centre]) + Vector3::z()).norm() < 1e-6);
//! let rgb = scene.shade(&camera, &instances, &[Material::Uniform([1.0, 0.0, 0.0])],
//!                       &Lighting::default(), &out)?;
//! assert!(rgb[centre][0] > 0 && rgb[centre][1] == 0);
//! // Turning the can about its axis or flipping it over changes nothing it looks like.
//! let symmetry = can.symmetry()?;
//! assert_eq!((symmetry.continuous.len(), symmetry.discrete.len()), (1, 1));
//! # Ok::<(), depth_render::RenderError>(())
//! ```

mod camera;
mod colour_camera;
mod compare;
mod error;
mod mask_errors;
mod mesh;
mod mesh_io;
mod mesh_repair;
mod mesh_scale;
mod pixel_grid;
pub mod primitives;
mod render;
mod resting;
mod sampling;
mod sensor;
mod shading;
mod surface;
mod symmetry;
mod tile_cast;

pub use camera::PinholeCamera;
pub use colour_camera::ImageChain;
pub use compare::{depth_discrepancy, pixel_discrepancies, unproject, visible_surface_discrepancy};
pub use error::RenderError;
pub use mask_errors::MaskErrors;
pub use mesh::{TriangleMesh, bounding_box, max_distance};
pub use mesh_io::{LoadedMesh, Vertices, load_mesh, load_vertices, write_mesh_ply_to, write_ply};
pub use mesh_repair::MeshRepairs;
pub use mesh_scale::{PLAUSIBLE_SIZE_M, check_mesh_size};
pub use render::{Instance, NO_TRIANGLE, Rendering, Scene, Window};
pub use resting::{FACE_ANGLE_DEG, RestingPose, group_by_symmetry, resting_poses};
pub use sampling::sample_surface;
pub use sensor::{DepthSensor, SensorPreset};
pub use shading::{ImageTexture, Lighting, Material};
pub use symmetry::{Primitive, ShapeSymmetry};
