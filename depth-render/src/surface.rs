//! Per-pixel surface attributes of a [`Rendering`]: barycentric coordinates and normals.
use nalgebra::{Point3, Vector3};

use crate::{Instance, PinholeCamera, RenderError, Rendering, Scene};

/// The hit surface at one pixel.
pub(crate) struct SurfacePoint<'a> {
    /// Position of the instance in the rendered list.
    pub(crate) index: usize,
    pub(crate) instance: &'a Instance,
    pub(crate) mesh: usize,
    pub(crate) triangle: usize,
    /// Weights of the triangle's three corners.
    pub(crate) barycentric: [f64; 3],
    /// Unit ray direction (camera frame).
    pub(crate) view: Vector3<f64>,
}

impl Scene {
    /// Barycentric coordinates of each pixel's hit (weights of the hit triangle's corners, in
    /// the order of [`crate::TriangleMesh::triangles`]); `[0, 0, 0]` for background.
    pub fn barycentrics(
        &self,
        camera: &PinholeCamera,
        instances: &[Instance],
        rendering: &Rendering,
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        self.per_pixel(camera, instances, rendering, [0.0; 3], |point| {
            point.barycentric.map(|w| w as f32)
        })
    }

    /// Camera-frame unit normals of the triangles seen (outward as the mesh is wound);
    /// `[0, 0, 0]` for background.
    pub fn normals(
        &self,
        camera: &PinholeCamera,
        instances: &[Instance],
        rendering: &Rendering,
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        self.per_pixel(camera, instances, rendering, [0.0; 3], |point| {
            let normal = self.meshes()[point.mesh].triangle_normal(point.triangle);
            let normal = point.instance.camera_from_model.rotation * normal;
            [normal.x as f32, normal.y as f32, normal.z as f32]
        })
    }

    /// Evaluates `f` at the surface point of every hit pixel of `rendering`, `background`
    /// elsewhere.
    pub(crate) fn per_pixel<T: Copy>(
        &self,
        camera: &PinholeCamera,
        instances: &[Instance],
        rendering: &Rendering,
        background: T,
        f: impl Fn(&SurfacePoint) -> T,
    ) -> Result<Vec<T>, RenderError> {
        let window = rendering.window;
        let width = window.width() as usize;
        let mut out = vec![background; rendering.depth.len()];
        // Neighbouring pixels mostly see the same triangle: its camera-frame corners are kept.
        let mut last: Option<(u16, u32, [Point3<f64>; 3])> = None;
        for (i, (value, (&instance, &triangle))) in out
            .iter_mut()
            .zip(rendering.instance.iter().zip(&rendering.triangle))
            .enumerate()
        {
            let Some(k) = instance else { continue };
            let placed =
                instances
                    .get(usize::from(k))
                    .ok_or_else(|| RenderError::RenderingMismatch {
                        reason: format!("pixel {i} shows instance {k} of {}", instances.len()),
                    })?;
            let mesh = self
                .meshes()
                .get(placed.mesh)
                .filter(|mesh| (triangle as usize) < mesh.triangles().len())
                .ok_or_else(|| RenderError::RenderingMismatch {
                    reason: format!(
                        "pixel {i} shows triangle {triangle} of mesh {}",
                        placed.mesh
                    ),
                })?;
            let (u, v) = (
                f64::from(window.u0) + (i % width) as f64,
                f64::from(window.v0) + (i / width) as f64,
            );
            let view = Vector3::from(camera.ray_direction(u, v));
            let corners = match last {
                Some((seen, seen_triangle, corners)) if (seen, seen_triangle) == (k, triangle) => {
                    corners
                }
                _ => {
                    let corners = mesh
                        .corners(triangle as usize)
                        .map(|p| placed.camera_from_model * p.cast::<f64>());
                    last = Some((k, triangle, corners));
                    corners
                }
            };
            *value = f(&SurfacePoint {
                index: usize::from(k),
                instance: placed,
                mesh: placed.mesh,
                triangle: triangle as usize,
                barycentric: barycentric(&corners, &view),
                view: view.normalize(),
            });
        }
        Ok(out)
    }
}

/// Weights of the corners (camera frame) at the point where the ray from the origin along
/// `direction` meets their plane: the triple products of the opposite edges, normalised.
fn barycentric(corners: &[Point3<f64>; 3], direction: &Vector3<f64>) -> [f64; 3] {
    let [a, b, c] = corners.map(|p| p.coords);
    let weights = [
        direction.dot(&b.cross(&c)),
        direction.dot(&c.cross(&a)),
        direction.dot(&a.cross(&b)),
    ];
    let sum: f64 = weights.iter().sum();
    if sum == 0.0 {
        return [1.0 / 3.0; 3];
    }
    weights.map(|w| w / sum)
}
