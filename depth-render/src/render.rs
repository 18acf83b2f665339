//! Ray casting of posed meshes into depth and instance masks with obvhs compressed-wide BVHs.
use glam::Vec3A;
use nalgebra::{Isometry3, Point3};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use rayon::prelude::*;

use crate::{PinholeCamera, RenderError, TriangleMesh};

/// A pixel rectangle `[u0, u1) × [v0, v1)` of the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub u0: u32,
    /// First row.
    pub v0: u32,
    /// One past the last column.
    pub u1: u32,
    /// One past the last row.
    pub v1: u32,
}

impl Window {
    /// The whole image of `camera`.
    pub fn full(camera: &PinholeCamera) -> Self {
        Self {
            u0: 0,
            v0: 0,
            u1: camera.width,
            v1: camera.height,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.u1.saturating_sub(self.u0)
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.v1.saturating_sub(self.v0)
    }
}

/// One mesh of a [`Scene`] placed in the camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instance {
    /// Index of the mesh in the scene.
    pub mesh: usize,
    /// Model→camera pose (metres).
    pub camera_from_model: Isometry3<f64>,
}

impl Instance {
    /// Mesh `mesh` of the scene at the model→camera pose `camera_from_model`.
    pub fn new(mesh: usize, camera_from_model: Isometry3<f64>) -> Self {
        Self {
            mesh,
            camera_from_model,
        }
    }
}

/// A rendered window: z-depth in metres (0 where no surface was hit) and the index of the
/// instance seen at each pixel (`None` for background), row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendering {
    /// The pixels rendered.
    pub window: Window,
    /// z-depth per pixel (m), 0 for a miss.
    pub depth: Vec<f32>,
    /// Instance index per pixel.
    pub instance: Vec<Option<u16>>,
}

struct MeshBvh {
    bvh: CwBvh,
    /// Triangles in BVH primitive order (model frame).
    triangles: Vec<Triangle>,
}

/// Meshes with their BVHs, built once and rendered at any number of poses.
pub struct Scene {
    meshes: Vec<MeshBvh>,
}

impl Scene {
    /// Builds one BVH per mesh.
    pub fn new(meshes: &[TriangleMesh]) -> Self {
        let meshes = meshes
            .iter()
            .map(|mesh| {
                let triangles: Vec<Triangle> = (0..mesh.triangles().len())
                    .map(|t| {
                        let [v0, v1, v2] = mesh.corners(t).map(|p| Vec3A::new(p.x, p.y, p.z));
                        Triangle { v0, v1, v2 }
                    })
                    .collect();
                let bvh = build_cwbvh_from_tris(
                    &triangles,
                    BvhBuildParams::medium_build(),
                    &mut Default::default(),
                );
                let triangles = bvh
                    .primitive_indices
                    .iter()
                    .map(|&i| triangles[i as usize])
                    .collect();
                MeshBvh { bvh, triangles }
            })
            .collect();
        Self { meshes }
    }

    /// Renders `instances` seen by `camera` in `window` (clipped to the image), in parallel
    /// over rows.
    pub fn render(
        &self,
        camera: &PinholeCamera,
        instances: &[Instance],
        window: Window,
    ) -> Result<Rendering, RenderError> {
        for (instance, placed) in instances.iter().enumerate() {
            if placed.mesh >= self.meshes.len() {
                return Err(RenderError::UnknownMesh {
                    instance,
                    mesh: placed.mesh,
                    meshes: self.meshes.len(),
                });
            }
            let pose = placed.camera_from_model.to_homogeneous();
            if pose.iter().any(|v| !v.is_finite()) {
                return Err(RenderError::NonFinitePose { instance });
            }
        }
        let window = Window {
            u0: window.u0.min(camera.width),
            v0: window.v0.min(camera.height),
            u1: window.u1.min(camera.width),
            v1: window.v1.min(camera.height),
        };
        // Each instance sees the camera rays in its model frame: origin and rotated directions.
        let frames: Vec<(Vec3A, nalgebra::Matrix3<f32>)> = instances
            .iter()
            .map(|placed| {
                let model_from_camera = placed.camera_from_model.inverse();
                let origin = model_from_camera * Point3::origin();
                let rotation = model_from_camera
                    .rotation
                    .to_rotation_matrix()
                    .into_inner()
                    .cast::<f32>();
                (
                    Vec3A::new(origin.x as f32, origin.y as f32, origin.z as f32),
                    rotation,
                )
            })
            .collect();
        let (width, height) = (window.width() as usize, window.height() as usize);
        let mut depth = vec![0.0f32; width * height];
        let mut instance = vec![None; width * height];
        depth
            .par_chunks_mut(width.max(1))
            .zip(instance.par_chunks_mut(width.max(1)))
            .enumerate()
            .for_each(|(row, (depth_row, instance_row))| {
                let v = f64::from(window.v0) + row as f64;
                for (column, (d, id)) in depth_row
                    .iter_mut()
                    .zip(instance_row.iter_mut())
                    .enumerate()
                {
                    let u = f64::from(window.u0) + column as f64;
                    let [x, y, z] = camera.ray_direction(u, v).map(|c| c as f32);
                    let direction = nalgebra::Vector3::new(x, y, z);
                    let mut nearest = f32::INFINITY;
                    for (k, (placed, (origin, rotation))) in
                        instances.iter().zip(&frames).enumerate()
                    {
                        let local = rotation * direction;
                        let mesh = &self.meshes[placed.mesh];
                        let ray =
                            Ray::new(*origin, Vec3A::new(local.x, local.y, local.z), 0.0, nearest);
                        let mut hit = RayHit::none();
                        if mesh
                            .bvh
                            .ray_traverse(ray, &mut hit, |r, i| mesh.triangles[i].intersect(r))
                            && hit.t < nearest
                        {
                            nearest = hit.t;
                            *id = u16::try_from(k).ok();
                        }
                    }
                    if nearest.is_finite() {
                        *d = nearest;
                    }
                }
            });
        Ok(Rendering {
            window,
            depth,
            instance,
        })
    }
}
