//! Casting the rays of a square tile of pixels together through one mesh's BVH.
//!
//! The tile's rays form a frustum with its apex at the camera centre. The BVH (obvhs' binary
//! PLOC build) is traversed once per tile, front to back, culling nodes outside the frustum or
//! behind the farthest depth found so far in the tile; each surviving triangle is intersected
//! with the rays of the pixels inside its projected bounding box.
//!
//! The ray–triangle test is exact and watertight: with the camera at the origin, the ray
//! `d = (x, y, 1)` meets triangle `ABC` iff the three triple products `d·(A×B)`, `d·(B×C)`,
//! `d·(C×A)` have the same sign (pixels on an edge belong to both triangles). An edge shared by
//! two triangles yields exactly negated products in both, so no ray slips through a seam. The
//! hit's z-depth is `n·A / n·d` with `n = (B−A)×(C−A)`.
use nalgebra::{Isometry3, Matrix3, Vector3};
use obvhs::BvhBuildParams;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::triangle::Triangle;

use crate::TriangleMesh;

/// Tile edge length in pixels.
pub(crate) const TILE: usize = 16;

/// A BVH node as centre and half-extent; a leaf when `count > 0`.
#[derive(Clone, Copy)]
struct Node {
    centre: [f32; 3],
    half: [f32; 3],
    /// Triangles in the leaf (0 for an inner node).
    count: u32,
    /// First triangle of a leaf, or the first of an inner node's two adjacent children.
    first: u32,
}

/// One mesh's BVH with its triangles in leaf order.
pub(crate) struct MeshBvh {
    nodes: Vec<Node>,
    /// Corners of the triangles in leaf order (model frame).
    corners: Vec<[[f32; 3]; 3]>,
    /// Mesh triangle index of each leaf-order triangle.
    original: Vec<u32>,
}

impl MeshBvh {
    pub(crate) fn new(mesh: &TriangleMesh) -> Self {
        let triangles: Vec<Triangle> = (0..mesh.triangles().len())
            .map(|t| {
                // `.into()` builds obvhs' own `Vec3A` (the glam it resolved to): naming glam
                // here would need a requirement that resolves to the same version.
                let [v0, v1, v2] = mesh.corners(t).map(|p| [p.x, p.y, p.z].into());
                Triangle { v0, v1, v2 }
            })
            .collect();
        let params = BvhBuildParams {
            max_prims_per_leaf: 4,
            ..BvhBuildParams::fast_build()
        };
        let bvh = build_bvh2_from_tris(&triangles, params, &mut Default::default());
        let nodes = bvh
            .nodes
            .iter()
            .map(|node| {
                let (lo, hi) = (node.aabb.min, node.aabb.max);
                Node {
                    centre: ((lo + hi) * 0.5).to_array(),
                    half: ((hi - lo) * 0.5).to_array(),
                    count: node.prim_count,
                    first: node.first_index,
                }
            })
            .collect();
        let original = bvh.primitive_indices.clone();
        let corners = original
            .iter()
            .map(|&t| mesh.corners(t as usize).map(|p| [p.x, p.y, p.z]))
            .collect();
        Self {
            nodes,
            corners,
            original,
        }
    }
}

/// A mesh placed in the camera frame, in single precision.
pub(crate) struct Placement {
    rotation: Matrix3<f32>,
    translation: Vector3<f32>,
}

impl Placement {
    pub(crate) fn new(camera_from_model: &Isometry3<f64>) -> Self {
        Self {
            rotation: camera_from_model
                .rotation
                .to_rotation_matrix()
                .into_inner()
                .cast(),
            translation: camera_from_model.translation.vector.cast(),
        }
    }

    fn apply(&self, p: &[f32; 3]) -> Vector3<f32> {
        self.rotation * Vector3::from(*p) + self.translation
    }
}

/// The pixels of one tile: ray coordinates `x = (u − cx)/fx` of its columns and `y` of its rows.
pub(crate) struct Tile<'a> {
    /// Image column and row of the tile's first pixel.
    pub(crate) origin: (u32, u32),
    pub(crate) xs: &'a [f32],
    pub(crate) ys: &'a [f32],
    /// Focal lengths and principal point, to bound triangles' projections.
    pub(crate) intrinsics: [f32; 4],
}

/// The nearest hits found so far in a tile, row-major with the tile's width.
pub(crate) struct TileHits {
    pub(crate) depth: [f32; TILE * TILE],
    pub(crate) instance: [u16; TILE * TILE],
    pub(crate) triangle: [u32; TILE * TILE],
}

impl TileHits {
    pub(crate) fn new() -> Self {
        Self {
            depth: [f32::INFINITY; TILE * TILE],
            instance: [0; TILE * TILE],
            triangle: [0; TILE * TILE],
        }
    }
}

/// A plane `n·p + offset ≥ 0` (inside) expressed in the model frame, with `|n|` for box bounds.
#[derive(Clone, Copy)]
struct ModelPlane {
    normal: [f32; 3],
    abs_normal: [f32; 3],
    offset: f32,
}

impl ModelPlane {
    /// The camera-frame plane `camera_normal·p ≥ 0` through the camera centre.
    fn new(camera_normal: Vector3<f32>, placement: &Placement) -> Self {
        let normal = placement.rotation.transpose() * camera_normal;
        Self {
            normal: normal.into(),
            abs_normal: normal.abs().into(),
            offset: camera_normal.dot(&placement.translation),
        }
    }

    /// `(lowest, highest)` value of `n·p + offset` over the node's box.
    #[inline(always)]
    fn range_over(&self, node: &Node) -> (f32, f32) {
        let (n, a, c, h) = (self.normal, self.abs_normal, node.centre, node.half);
        let mid = n[0] * c[0] + n[1] * c[1] + n[2] * c[2] + self.offset;
        let spread = a[0] * h[0] + a[1] * h[1] + a[2] * h[2];
        (mid - spread, mid + spread)
    }
}

/// The tile's frustum in the model frame: four side planes and the camera's depth axis.
struct Frustum {
    sides: [ModelPlane; 4],
    depth: ModelPlane,
}

impl Frustum {
    /// The frustum of the tile's sample rays, widened by a hair against rounding.
    fn new(tile: &Tile, placement: &Placement) -> Self {
        let margin = 1e-6;
        let (x_lo, x_hi) = (tile.xs[0] - margin, tile.xs[tile.xs.len() - 1] + margin);
        let (y_lo, y_hi) = (tile.ys[0] - margin, tile.ys[tile.ys.len() - 1] + margin);
        let side = |n: Vector3<f32>| ModelPlane::new(n, placement);
        Self {
            sides: [
                side(Vector3::new(1.0, 0.0, -x_lo)),
                side(Vector3::new(-1.0, 0.0, x_hi)),
                side(Vector3::new(0.0, 1.0, -y_lo)),
                side(Vector3::new(0.0, -1.0, y_hi)),
            ],
            depth: side(Vector3::z()),
        }
    }

    /// The node's nearest camera z if some of it may be in front of the camera and inside the
    /// frustum, else `None`.
    #[inline(always)]
    fn nearest(&self, node: &Node) -> Option<f32> {
        let (near, far) = self.depth.range_over(node);
        let outside = far <= 0.0
            || self.sides[0].range_over(node).1 < 0.0
            || self.sides[1].range_over(node).1 < 0.0
            || self.sides[2].range_over(node).1 < 0.0
            || self.sides[3].range_over(node).1 < 0.0;
        (!outside).then_some(near)
    }
}

/// Casts the tile's rays at mesh `bvh` placed by `placement`, keeping the nearest hits in `hits`
/// (labelled `instance`). `stack` is scratch space reused between calls.
pub(crate) fn cast_tile(
    bvh: &MeshBvh,
    placement: &Placement,
    instance: u16,
    tile: &Tile,
    hits: &mut TileHits,
    stack: &mut Vec<(u32, f32)>,
) {
    let frustum = Frustum::new(tile, placement);
    let pixels = tile.xs.len() * tile.ys.len();
    let farthest_of = |hits: &TileHits| hits.depth[..pixels].iter().copied().fold(0.0, f32::max);
    let mut farthest = farthest_of(hits);

    stack.clear();
    if let Some(near) = frustum.nearest(&bvh.nodes[0]) {
        stack.push((0, near));
    }
    while let Some((index, nearest)) = stack.pop() {
        if nearest > farthest {
            continue;
        }
        let node = &bvh.nodes[index as usize];
        if node.count > 0 {
            let first = node.first as usize;
            for k in first..first + node.count as usize {
                if intersect_triangle(bvh, k, placement, instance, tile, hits) {
                    farthest = farthest_of(hits);
                }
            }
            continue;
        }
        let (left, right) = (node.first, node.first + 1);
        let near_left = frustum.nearest(&bvh.nodes[left as usize]);
        let near_right = frustum.nearest(&bvh.nodes[right as usize]);
        // Push the farther child first so that the nearer one is popped next.
        let (first, second) = match (near_left, near_right) {
            (Some(l), Some(r)) if l <= r => ((right, r), Some((left, l))),
            (Some(l), Some(r)) => ((left, l), Some((right, r))),
            (Some(l), None) => ((left, l), None),
            (None, Some(r)) => ((right, r), None),
            (None, None) => continue,
        };
        for (child, near) in std::iter::once(first).chain(second) {
            if near <= farthest {
                stack.push((child, near));
            }
        }
    }
}

/// Intersects leaf-order triangle `k` with the tile's rays; true when some pixel got nearer.
fn intersect_triangle(
    bvh: &MeshBvh,
    k: usize,
    placement: &Placement,
    instance: u16,
    tile: &Tile,
    hits: &mut TileHits,
) -> bool {
    let corners = &bvh.corners[k];
    let (a, b, c) = (
        placement.apply(&corners[0]),
        placement.apply(&corners[1]),
        placement.apply(&corners[2]),
    );
    let (width, height) = (tile.xs.len(), tile.ys.len());
    let (columns, rows) = match projected_bounds(&[a, b, c], tile) {
        Some(bounds) => bounds,
        None if a.z > 0.0 || b.z > 0.0 || c.z > 0.0 => ((0, width), (0, height)),
        None => return false,
    };
    if columns.0 >= columns.1 || rows.0 >= rows.1 {
        return false;
    }
    let edges = [a.cross(&b), b.cross(&c), c.cross(&a)];
    let normal = (b - a).cross(&(c - a));
    let offset = normal.dot(&a);
    let mut improved = false;
    for row in rows.0..rows.1 {
        let y = tile.ys[row];
        let (e0, e1, e2) = (
            y * edges[0].y + edges[0].z,
            y * edges[1].y + edges[1].z,
            y * edges[2].y + edges[2].z,
        );
        let denominator_row = y * normal.y + normal.z;
        for column in columns.0..columns.1 {
            let x = tile.xs[column];
            let (s0, s1, s2) = (
                x * edges[0].x + e0,
                x * edges[1].x + e1,
                x * edges[2].x + e2,
            );
            let inside =
                (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) || (s0 <= 0.0 && s1 <= 0.0 && s2 <= 0.0);
            if !inside {
                continue;
            }
            let t = offset / (x * normal.x + denominator_row);
            let pixel = row * width + column;
            if t > 0.0 && t < hits.depth[pixel] {
                hits.depth[pixel] = t;
                hits.instance[pixel] = instance;
                hits.triangle[pixel] = bvh.original[k];
                improved = true;
            }
        }
    }
    improved
}

/// The tile columns and rows (half-open) inside the triangle's projected bounding box, or
/// `None` when a corner is not in front of the camera.
fn projected_bounds(
    corners: &[Vector3<f32>; 3],
    tile: &Tile,
) -> Option<((usize, usize), (usize, usize))> {
    const NEAR: f32 = 1e-6;
    if corners.iter().any(|p| p.z <= NEAR) {
        return None;
    }
    let [fx, fy, cx, cy] = tile.intrinsics;
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
    );
    for p in corners {
        let (x, y) = (p.x / p.z, p.y / p.z);
        x_lo = x_lo.min(x);
        x_hi = x_hi.max(x);
        y_lo = y_lo.min(y);
        y_hi = y_hi.max(y);
    }
    // Pixel coordinates, widened by a thousandth of a pixel: the exact edge test decides.
    let span = |lo: f32, hi: f32, f: f32, c: f32, first: f32, count: usize| {
        // Truncation toward zero is floor/ceil on these shifted, non-negative values.
        let lo = (lo * f + c - 1e-3 - first).max(-1.0) + 1.0;
        let hi = (hi * f + c + 1e-3 - first + 1.0).clamp(0.0, count as f32);
        let (lo, hi) = (lo as usize, hi as usize);
        if hi <= lo { (0, 0) } else { (lo, hi) }
    };
    let (first_column, first_row) = (tile.origin.0 as f32, tile.origin.1 as f32);
    Some((
        span(x_lo, x_hi, fx, cx, first_column, tile.xs.len()),
        span(y_lo, y_hi, fy, cy, first_row, tile.ys.len()),
    ))
}
