//! Shaded RGB images: ambient + Lambert + a Blinn–Phong highlight under one coloured
//! directional light, with per-instance [`Material`]s (a flat colour, vertex colours, an image
//! texture at the mesh's texture coordinates or projected onto a mesh without them, or a
//! procedural pattern that breaks an object's visual symmetry without changing its geometry).
use nalgebra::{Point3, Vector3};

use crate::surface::SurfacePoint;
use crate::{Instance, PinholeCamera, RenderError, Rendering, Scene, TriangleMesh};

/// How the surface of an instance is coloured (linear RGB in `[0, 1]`).
#[derive(Debug, Clone, PartialEq)]
pub enum Material {
    /// One colour everywhere (the paper's "Uniform" datasets).
    Uniform([f32; 3]),
    /// The mesh's per-vertex colours, interpolated.
    VertexColors,
    /// An image sampled at the mesh's texture coordinates.
    Image(ImageTexture),
    /// An image repeated every `tile` metres over model space and projected onto each
    /// triangle along the model axis nearest its normal (a triplanar mapping): a texture for
    /// meshes without texture coordinates (tables, distractors).
    Projected {
        /// The image.
        texture: ImageTexture,
        /// Model-space size of one repeat (m).
        tile: f32,
    },
    /// Model-space cubes of side `cell` (metres), each a colour drawn from a seeded hash: a
    /// solid texture that makes every orientation of a symmetric shape look different (the
    /// paper's "Texture" datasets).
    Patches {
        /// Edge of a cube of uniform colour (m).
        cell: f32,
        /// Seed of the colours.
        seed: u64,
    },
}

/// An RGB image for texturing, sampled bilinearly with wrap-around; `v = 0` is the bottom row
/// (the OBJ/PLY convention). Clones share the texels.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageTexture {
    width: usize,
    height: usize,
    texels: std::sync::Arc<[[f32; 3]]>,
}

impl ImageTexture {
    /// A texture from row-major RGB texels in `[0, 1]`, top row first.
    pub fn new(width: usize, height: usize, texels: Vec<[f32; 3]>) -> Result<Self, RenderError> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(RenderError::InvalidTexture {
                reason: format!("{} texels for {width}×{height}", texels.len()),
            });
        }
        if texels.iter().flatten().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(RenderError::InvalidTexture {
                reason: "texel outside [0, 1]".into(),
            });
        }
        Ok(Self {
            width,
            height,
            texels: texels.into(),
        })
    }

    /// Columns and rows.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The texels as 8-bit RGB, row-major, top row first (as [`ImageTexture::new`] takes them).
    pub fn to_rgb8(&self) -> Vec<[u8; 3]> {
        self.texels
            .iter()
            .map(|t| t.map(|c| (c * 255.0).round().clamp(0.0, 255.0) as u8))
            .collect()
    }

    /// The colour at texture coordinates `(u, v)`.
    pub fn sample(&self, u: f32, v: f32) -> [f32; 3] {
        let x = u.rem_euclid(1.0) * self.width as f32 - 0.5;
        let y = (1.0 - v.rem_euclid(1.0)) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |i: f32, j: f32| {
            let i = (i as i64).rem_euclid(self.width as i64) as usize;
            let j = (j as i64).rem_euclid(self.height as i64) as usize;
            self.texels[j * self.width + i]
        };
        let (a, b, c, d) = (
            texel(x0, y0),
            texel(x0 + 1.0, y0),
            texel(x0, y0 + 1.0),
            texel(x0 + 1.0, y0 + 1.0),
        );
        std::array::from_fn(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    }
}

/// A directional light and the background colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Direction from the surface towards the light (camera frame; normalised on use).
    pub towards_light: Vector3<f64>,
    /// Ambient fraction of the albedo.
    pub ambient: f32,
    /// Diffuse (Lambert) fraction of the albedo.
    pub diffuse: f32,
    /// The light's colour, multiplying its diffuse and specular parts (white: `[1, 1, 1]`).
    pub colour: [f32; 3],
    /// Strength of the Blinn–Phong highlight, added in the light's colour (0: matte).
    pub specular: f32,
    /// Blinn–Phong exponent: larger is a smaller, sharper highlight.
    pub shininess: f32,
    /// Colour of pixels where nothing was hit (8-bit RGB).
    pub background: [u8; 3],
}

impl Default for Lighting {
    /// A white light above and slightly left of the camera, 30% ambient, matte surfaces, black
    /// background.
    fn default() -> Self {
        Self {
            towards_light: Vector3::new(-0.3, -0.6, -1.0),
            ambient: 0.3,
            diffuse: 0.7,
            colour: [1.0; 3],
            specular: 0.0,
            shininess: 20.0,
            background: [0, 0, 0],
        }
    }
}

impl Scene {
    /// The shaded 8-bit RGB image of `rendering`: per channel, `albedo · (ambient + diffuse ·
    /// max(0, n·l) · colour) + specular · max(0, n·h)^shininess · colour` (the highlight only
    /// where `n·l > 0`), with `n` the interpolated vertex normal (the face normal for meshes
    /// without normals) turned towards the camera and `h` the half-way vector between the
    /// light and the camera. `materials[k]` colours `instances[k]`.
    pub fn shade(
        &self,
        camera: &PinholeCamera,
        instances: &[Instance],
        materials: &[Material],
        lighting: &Lighting,
        rendering: &Rendering,
    ) -> Result<Vec<[u8; 3]>, RenderError> {
        if materials.len() != instances.len() {
            return Err(RenderError::RenderingMismatch {
                reason: format!(
                    "{} materials for {} instances",
                    materials.len(),
                    instances.len()
                ),
            });
        }
        for (k, (material, placed)) in materials.iter().zip(instances).enumerate() {
            let mesh = self.meshes().get(placed.mesh);
            let missing = match material {
                Material::VertexColors => mesh.is_some_and(|m| m.colors().is_none()),
                Material::Image(_) => mesh.is_some_and(|m| m.uvs().is_none()),
                Material::Uniform(_) | Material::Projected { .. } | Material::Patches { .. } => {
                    false
                }
            };
            if missing {
                return Err(RenderError::RenderingMismatch {
                    reason: format!(
                        "material of instance {k} needs vertex attributes its mesh lacks"
                    ),
                });
            }
        }
        let light = lighting.towards_light.normalize();
        self.per_pixel(camera, instances, rendering, lighting.background, |point| {
            let mesh = &self.meshes()[point.mesh];
            let albedo = albedo(mesh, point, &materials[point.index]);
            let mut normal = point.instance.camera_from_model.rotation * normal(mesh, point);
            if normal.dot(&point.view) > 0.0 {
                normal = -normal;
            }
            let lambert = normal.dot(&light).max(0.0) as f32;
            let highlight = if lighting.specular > 0.0 && lambert > 0.0 {
                let half = (light - point.view.normalize()).normalize();
                lighting.specular * (normal.dot(&half).max(0.0) as f32).powf(lighting.shininess)
            } else {
                0.0
            };
            std::array::from_fn(|k| {
                let light = lighting.colour[k];
                let c = albedo[k] * (lighting.ambient + lighting.diffuse * lambert * light)
                    + highlight * light;
                (c * 255.0).round().clamp(0.0, 255.0) as u8
            })
        })
    }
}

/// Interpolates a per-vertex attribute of the point's triangle.
fn interpolate<const N: usize>(
    values: &[[f32; N]],
    mesh: &TriangleMesh,
    point: &SurfacePoint,
) -> [f32; N] {
    let corners = mesh.triangles()[point.triangle];
    std::array::from_fn(|k| {
        (0..3)
            .map(|c| point.barycentric[c] as f32 * values[corners[c] as usize][k])
            .sum()
    })
}

fn normal(mesh: &TriangleMesh, point: &SurfacePoint) -> Vector3<f64> {
    match mesh.normals() {
        Some(normals) => {
            let corners = mesh.triangles()[point.triangle];
            let n: Vector3<f64> = (0..3)
                .map(|c| normals[corners[c] as usize].cast::<f64>() * point.barycentric[c])
                .sum();
            n.try_normalize(1e-12)
                .unwrap_or_else(|| mesh.triangle_normal(point.triangle))
        }
        None => mesh.triangle_normal(point.triangle),
    }
}

fn albedo(mesh: &TriangleMesh, point: &SurfacePoint, material: &Material) -> [f32; 3] {
    match material {
        Material::Uniform(color) => *color,
        Material::VertexColors => interpolate(mesh.colors().unwrap_or_default(), mesh, point),
        Material::Image(texture) => {
            let [u, v] = interpolate(mesh.uvs().unwrap_or_default(), mesh, point);
            texture.sample(u, v)
        }
        Material::Projected { texture, tile } => {
            let p = model_point(mesh, point);
            let n = mesh.triangle_normal(point.triangle).abs();
            // The two axes across the one the triangle faces most.
            let (a, b) = if n.x >= n.y && n.x >= n.z {
                (1, 2)
            } else if n.y >= n.z {
                (0, 2)
            } else {
                (0, 1)
            };
            let tile = f64::from(*tile);
            texture.sample((p[a] / tile) as f32, (p[b] / tile) as f32)
        }
        Material::Patches { cell, seed } => {
            patch_color(&model_point(mesh, point), f64::from(*cell), *seed)
        }
    }
}

/// The surface point in the mesh's frame.
fn model_point(mesh: &TriangleMesh, point: &SurfacePoint) -> Point3<f64> {
    let corners = mesh.corners(point.triangle);
    Point3::from(
        (0..3)
            .map(|c| corners[c].coords.cast::<f64>() * point.barycentric[c])
            .sum::<Vector3<f64>>(),
    )
}

/// The colour of the model-space cube of side `cell` holding `p`: a hash of its integer
/// coordinates and the seed picks a hue, saturation and value.
fn patch_color(p: &Point3<f64>, cell: f64, seed: u64) -> [f32; 3] {
    let key = p
        .iter()
        .map(|c| (c / cell).floor() as i64 as u64)
        .fold(seed, |h, c| splitmix(h ^ c));
    let hue = (key & 0xffff) as f32 / 65536.0;
    let saturation = 0.5 + 0.5 * ((key >> 16) & 0xff) as f32 / 255.0;
    let value = 0.4 + 0.6 * ((key >> 24) & 0xff) as f32 / 255.0;
    hsv_to_rgb(hue, saturation, value)
}

/// SplitMix64's finaliser: a well-mixed 64-bit hash.
fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn hsv_to_rgb(hue: f32, saturation: f32, value: f32) -> [f32; 3] {
    let h = hue * 6.0;
    let f = h - h.floor();
    let (p, q, t) = (
        value * (1.0 - saturation),
        value * (1.0 - saturation * f),
        value * (1.0 - saturation * (1.0 - f)),
    );
    match h as u32 % 6 {
        0 => [value, t, p],
        1 => [q, value, p],
        2 => [p, value, t],
        3 => [p, q, value],
        4 => [t, p, value],
        _ => [value, p, q],
    }
}
