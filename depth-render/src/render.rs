//! Scenes of posed meshes rendered into depth, instance and triangle maps, tile by tile in
//! parallel (see [`crate::tile_cast`] for the ray casting itself).
use std::ops::Range;

use nalgebra::Isometry3;
use rayon::prelude::*;

use crate::tile_cast::{MeshBvh, Placement, TILE, Tile, TileHits, cast_tile};
use crate::{PinholeCamera, RenderError, TriangleMesh};

/// The triangle index of background pixels in [`Rendering::triangle`].
pub const NO_TRIANGLE: u32 = u32::MAX;

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

/// A rendered window, row-major: z-depth in metres (0 where no surface was hit), the index of
/// the instance seen at each pixel (`None` for background) and the index of the mesh triangle
/// hit ([`NO_TRIANGLE`] for background).
#[derive(Debug, Clone, PartialEq)]
pub struct Rendering {
    /// The pixels rendered.
    pub window: Window,
    /// z-depth per pixel (m), 0 for a miss.
    pub depth: Vec<f32>,
    /// Instance index per pixel.
    pub instance: Vec<Option<u16>>,
    /// Triangle of the instance's mesh per pixel.
    pub triangle: Vec<u32>,
}

/// A band of rows of a [`Rendering`]'s maps, each row-major.
struct Band<'a> {
    depth: &'a mut [f32],
    instance: &'a mut [Option<u16>],
    triangle: &'a mut [u32],
}

/// The pixel centres of a window as ray directions: `x/z` of each column, `y/z` of each row.
struct WindowRays {
    window: Window,
    xs: Vec<f32>,
    ys: Vec<f32>,
    /// Focal lengths and principal point, to bound triangles' projections.
    intrinsics: [f32; 4],
}

impl WindowRays {
    fn new(camera: &PinholeCamera, window: Window) -> Self {
        let xs: Vec<f32> = (window.u0..window.u1)
            .map(|u| ((f64::from(u) - camera.cx) / camera.fx) as f32)
            .collect();
        let ys: Vec<f32> = (window.v0..window.v1)
            .map(|v| ((f64::from(v) - camera.cy) / camera.fy) as f32)
            .collect();
        let intrinsics = [camera.fx, camera.fy, camera.cx, camera.cy].map(|c| c as f32);
        Self {
            window,
            xs,
            ys,
            intrinsics,
        }
    }
}

/// Meshes with their BVHs, built once and rendered at any number of poses.
pub struct Scene {
    meshes: Vec<TriangleMesh>,
    bvhs: Vec<MeshBvh>,
}

impl Scene {
    /// Builds one BVH per mesh (in parallel).
    pub fn new(meshes: &[TriangleMesh]) -> Self {
        Self {
            meshes: meshes.to_vec(),
            bvhs: meshes.par_iter().map(MeshBvh::new).collect(),
        }
    }

    /// The scene's meshes, in the order given to [`Scene::new`].
    pub fn meshes(&self) -> &[TriangleMesh] {
        &self.meshes
    }

    /// Renders `instances` seen by `camera` in `window` (clipped to the image): one ray per
    /// pixel centre, in parallel over bands of tiles. At most 65,536 instances.
    pub fn render(
        &self,
        camera: &PinholeCamera,
        instances: &[Instance],
        window: Window,
    ) -> Result<Rendering, RenderError> {
        self.check(instances)?;
        let window = Window {
            u0: window.u0.min(camera.width),
            v0: window.v0.min(camera.height),
            u1: window.u1.min(camera.width),
            v1: window.v1.min(camera.height),
        };
        let placements: Vec<Placement> = instances
            .iter()
            .map(|placed| Placement::new(&placed.camera_from_model))
            .collect();
        let (width, height) = (window.width() as usize, window.height() as usize);
        let mut depth = vec![0.0f32; width * height];
        let mut instance = vec![None; width * height];
        let mut triangle = vec![NO_TRIANGLE; width * height];
        if width == 0 || height == 0 {
            return Ok(Rendering {
                window,
                depth,
                instance,
                triangle,
            });
        }
        let rays = WindowRays::new(camera, window);
        let band = width * TILE;
        depth
            .par_chunks_mut(band)
            .zip(instance.par_chunks_mut(band))
            .zip(triangle.par_chunks_mut(band))
            .enumerate()
            .for_each(|(b, ((depth, instance), triangle))| {
                let rows = b * TILE..(b * TILE + TILE).min(height);
                let band = Band {
                    depth,
                    instance,
                    triangle,
                };
                self.render_band(instances, &placements, &rays, rows, band);
            });
        Ok(Rendering {
            window,
            depth,
            instance,
            triangle,
        })
    }

    /// Renders the `rows` of the window into `band`: tile by tile, each tile against every
    /// instance.
    fn render_band(
        &self,
        instances: &[Instance],
        placements: &[Placement],
        rays: &WindowRays,
        rows: Range<usize>,
        band: Band<'_>,
    ) {
        let Band {
            depth,
            instance,
            triangle,
        } = band;
        let width = rays.xs.len();
        let mut stack = Vec::with_capacity(64);
        for columns in (0..width).step_by(TILE).map(|c| c..(c + TILE).min(width)) {
            let tile = Tile {
                origin: (
                    rays.window.u0 + columns.start as u32,
                    rays.window.v0 + rows.start as u32,
                ),
                xs: &rays.xs[columns.clone()],
                ys: &rays.ys[rows.clone()],
                intrinsics: rays.intrinsics,
            };
            let mut hits = TileHits::new();
            for (k, (placed, placement)) in instances.iter().zip(placements).enumerate() {
                let bvh = &self.bvhs[placed.mesh];
                cast_tile(bvh, placement, k as u16, &tile, &mut hits, &mut stack);
            }
            let tile_width = columns.len();
            for (r, row) in rows.clone().enumerate() {
                let out = (row - rows.start) * width + columns.start;
                for c in 0..tile_width {
                    let t = r * tile_width + c;
                    if hits.depth[t].is_finite() {
                        depth[out + c] = hits.depth[t];
                        instance[out + c] = Some(hits.instance[t]);
                        triangle[out + c] = hits.triangle[t];
                    }
                }
            }
        }
    }

    /// Rejects instances naming unknown meshes, with non-finite poses, or too many of them.
    fn check(&self, instances: &[Instance]) -> Result<(), RenderError> {
        if instances.len() > usize::from(u16::MAX) + 1 {
            return Err(RenderError::TooManyInstances {
                count: instances.len(),
            });
        }
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
        Ok(())
    }
}
