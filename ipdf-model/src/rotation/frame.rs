//! The frame a rotation model learns and answers in. A crop shows the object as seen along the
//! line of sight through the crop's centre, so one look of the object at two places in the
//! image is two rotations in the camera's frame, apart by up to the angle between the two lines
//! of sight (up to 13° between the quick pipeline's renders, 3–11° between the real YCB-Video
//! instances). A model in the camera's frame has to learn that spread from a crop that does
//! not show where it was cut. In the line of sight's frame (the allocentric rotation of Kundu
//! et al., 3D-RCNN, CVPR 2018) one look is one rotation, and the crop's geometry turns the
//! model's answers back into the camera's frame.
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::translation::CropGeometry;

/// The frame of the rotations a rotation model learns and answers in ([`crate::ModelConfig`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RotationFrame {
    /// The camera's: the rotation of the object's pose itself (checkpoints that name no frame).
    #[default]
    Camera,
    /// The camera's turned by the shortest turn that takes its optical axis onto the line of
    /// sight through the crop's centre ([`RotationFrame::to_camera`]).
    LineOfSight,
}

impl RotationFrame {
    /// `camera` or `line-of-sight`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Camera => "camera",
            Self::LineOfSight => "line-of-sight",
        }
    }

    /// Every frame.
    pub const ALL: [Self; 2] = [Self::Camera, Self::LineOfSight];

    /// Whether this is the camera's frame (what a checkpoint that names no frame means).
    pub fn is_camera(&self) -> bool {
        *self == Self::Camera
    }

    /// The turn that takes a rotation in this frame into the camera's for a crop cut at
    /// `geometry`: `R_camera = turn · R_model`. The identity for [`RotationFrame::Camera`]; for
    /// [`RotationFrame::LineOfSight`] the shortest turn taking the optical axis `z` onto the ray
    /// through the crop's centre ([`CropGeometry::ray`]), about an axis in the image plane.
    pub fn to_camera(self, geometry: &CropGeometry) -> UnitQuaternion<f64> {
        match self {
            Self::Camera => UnitQuaternion::identity(),
            // The ray points forwards (z = 1), so it is never opposite z.
            Self::LineOfSight => UnitQuaternion::rotation_between(&Vector3::z(), &geometry.ray())
                .unwrap_or_else(UnitQuaternion::identity),
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::CropBox;
    use crate::translation::CameraIntrinsics;

    fn geometry(u: f64, v: f64) -> CropGeometry {
        CropGeometry {
            crop: CropBox {
                centre_x: u,
                centre_y: v,
                side: 60.0,
            },
            intrinsics: CameraIntrinsics {
                fx: 1066.8,
                fy: 1067.5,
                cx: 313.0,
                cy: 241.3,
            },
            width: 640,
            height: 480,
        }
    }

    #[test]
    fn a_crop_on_the_principal_point_sees_along_the_optical_axis() {
        // Pixel centres sit at integers, so the principal point is the pixel square's centre
        // at (cx + ½, cy + ½) in the crop box's coordinates.
        let turn = RotationFrame::LineOfSight.to_camera(&geometry(313.5, 241.8));
        assert!(turn.angle() < 1e-12, "{}", turn.angle());
        let camera = RotationFrame::Camera.to_camera(&geometry(600.0, 30.0));
        assert_eq!(camera, UnitQuaternion::identity());
    }

    proptest! {
        /// Written out from the pinhole model: the turn takes `z` onto the unit ray through the
        /// crop's centre, `((u − ½ − cx)/fx, (v − ½ − cy)/fy, 1)`, by the angle between the two
        /// (the shortest turn: its axis is square to both, so it has no roll about the ray).
        #[test]
        fn the_turn_takes_the_optical_axis_onto_the_crop_centre_ray(
            u in 0.0f64..640.0,
            v in 0.0f64..480.0,
            angle in -3.0f64..3.0,
        ) {
            let g = geometry(u, v);
            let k = &g.intrinsics;
            let ray = Vector3::new((u - 0.5 - k.cx) / k.fx, (v - 0.5 - k.cy) / k.fy, 1.0)
                .normalize();
            let turn = RotationFrame::LineOfSight.to_camera(&g);
            prop_assert!((turn * Vector3::z() - ray).norm() < 1e-12);
            prop_assert!((turn.angle() - ray.z.acos()).abs() < 1e-12);
            if let Some(axis) = turn.axis() {
                prop_assert!(axis.z.abs() < 1e-12 && axis.dot(&ray).abs() < 1e-12);
            }
            // A model-frame rotation and back: R = turn⁻¹ · (turn · R).
            let r = UnitQuaternion::from_euler_angles(angle, 0.5 * angle, -angle);
            let back = turn.inverse() * (turn * r);
            prop_assert!(back.angle_to(&r) < 1e-12);
        }
    }
}
