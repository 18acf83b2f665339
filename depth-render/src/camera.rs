//! The pinhole camera: OpenCV axes (x right, y down, z forward), pixel centres at integer
//! coordinates (as BOP's `cam_K`), depth measured along z.
use nalgebra::{Point2, Point3};

use crate::RenderError;

/// Pinhole intrinsics in pixels and the image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    /// Focal length along x (pixels).
    pub fx: f64,
    /// Focal length along y (pixels).
    pub fy: f64,
    /// Principal point x (pixels).
    pub cx: f64,
    /// Principal point y (pixels).
    pub cy: f64,
    /// Image width (pixels).
    pub width: u32,
    /// Image height (pixels).
    pub height: u32,
}

impl PinholeCamera {
    /// A camera from intrinsics; rejects non-positive or non-finite focal lengths, a non-finite
    /// principal point and a zero image size.
    pub fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
    ) -> Result<Self, RenderError> {
        let invalid = |reason: String| Err(RenderError::InvalidCamera { reason });
        if !(fx.is_finite() && fx > 0.0 && fy.is_finite() && fy > 0.0) {
            return invalid(format!(
                "focal lengths must be positive, got fx = {fx}, fy = {fy}"
            ));
        }
        if !(cx.is_finite() && cy.is_finite()) {
            return invalid(format!("principal point ({cx}, {cy}) is not finite"));
        }
        if width == 0 || height == 0 {
            return invalid(format!("image size {width}×{height} is empty"));
        }
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        })
    }

    /// The direction through pixel `(u, v)` scaled to unit z, so that the ray parameter of a
    /// hit equals its z-depth.
    pub fn ray_direction(&self, u: f64, v: f64) -> [f64; 3] {
        [(u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0]
    }

    /// The pixel coordinates of a camera-frame point (`None` behind the camera).
    pub fn project(&self, point: &Point3<f64>) -> Option<Point2<f64>> {
        (point.z > 0.0).then(|| {
            Point2::new(
                self.fx * point.x / point.z + self.cx,
                self.fy * point.y / point.z + self.cy,
            )
        })
    }

    /// The camera-frame point at pixel `(u, v)` and z-depth `depth`.
    pub fn unproject(&self, u: f64, v: f64, depth: f64) -> Point3<f64> {
        let [x, y, z] = self.ray_direction(u, v);
        Point3::new(x * depth, y * depth, z * depth)
    }
}
