//! Where a crop came from: its box in the image and the camera's intrinsics, and the crop-relative
//! coordinates of translation queries that the translation model encodes.
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor};

use crate::{CropBox, ModelError};

/// Pinhole intrinsics in pixels, BOP / OpenCV convention: a camera-frame point `(x, y, z)`
/// projects to `(fx·x/z + cx, fy·y/z + cy)` with pixel centres at integer coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Focal length along `x`, pixels.
    pub fx: f64,
    /// Focal length along `y`, pixels.
    pub fy: f64,
    /// Principal point `x`, pixels.
    pub cx: f64,
    /// Principal point `y`, pixels.
    pub cy: f64,
}

/// A crop's box, the intrinsics of its camera, and the image size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CropGeometry {
    /// The crop's square in the image.
    pub crop: CropBox,
    /// The camera.
    pub intrinsics: CameraIntrinsics,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

/// Values per image of [`crop_factors`].
pub(crate) const FACTORS: i64 = 5;
/// Values per image of [`crop_features`].
pub(crate) const FEATURES: i64 = 3;

impl CropGeometry {
    /// Checks that every value is finite, focal lengths and the side are positive, and the
    /// principal point and the crop's centre lie in the image; `image` names the image in the
    /// error.
    pub fn validate(&self, image: usize) -> Result<(), ModelError> {
        let k = &self.intrinsics;
        let c = &self.crop;
        let values = [k.fx, k.fy, k.cx, k.cy, c.centre_x, c.centre_y, c.side];
        let reason = if !values.iter().all(|v| v.is_finite()) {
            Some(format!("{self:?}: not finite"))
        } else if k.fx <= 0.0 || k.fy <= 0.0 || c.side <= 0.0 {
            Some(format!(
                "focal lengths {} and {} and crop side {}: need > 0",
                k.fx, k.fy, c.side
            ))
        } else if !(0.0..=self.width as f64).contains(&k.cx)
            || !(0.0..=self.height as f64).contains(&k.cy)
        {
            Some(format!(
                "principal point ({}, {}) lies outside the {} × {} image",
                k.cx, k.cy, self.width, self.height
            ))
        } else if !(0.0..=self.width as f64).contains(&c.centre_x)
            || !(0.0..=self.height as f64).contains(&c.centre_y)
        {
            Some(format!(
                "crop centre ({}, {}) lies outside the {} × {} image",
                c.centre_x, c.centre_y, self.width, self.height
            ))
        } else {
            None
        };
        match reason {
            Some(reason) => Err(ModelError::CropGeometry { image, reason }),
            None => Ok(()),
        }
    }

    /// The ray through the crop's centre, `((u₀ − ½ − cx)/fx, (v₀ − ½ − cy)/fy, 1)` (the
    /// crop box's coordinates put pixel centres at half-integers, the intrinsics' at integers).
    pub fn ray(&self) -> Vector3<f64> {
        let (k, c) = (&self.intrinsics, &self.crop);
        Vector3::new(
            (c.centre_x - 0.5 - k.cx) / k.fx,
            (c.centre_y - 0.5 - k.cy) / k.fy,
            1.0,
        )
    }

    /// The geometric mean of the focal lengths, pixels.
    fn focal(&self) -> f64 {
        (self.intrinsics.fx * self.intrinsics.fy).sqrt()
    }

    /// The crop's side in mm at depth `z` mm: `z · side / f`.
    pub fn metric_side(&self, z: f64) -> f64 {
        z * self.crop.side / self.focal()
    }
}

/// The crop-relative coordinates of translations, `[…, 3]` from `[…, 3]` (mm), for per-image
/// factors `[…, 5]` of [`crop_factors`] (broadcast):
/// `u = 2 (fx·x/z + cx + ½ − u₀) / s` and `v` alike (the crop spans `[−1, 1]`), and
/// `w = 2 ln(z · s / (f · E))` (0 where the crop's side at depth `z` is `E`, the model's
/// reference extent). An object's centre sits near `(0, 0, 0)` in every image, however far and
/// wherever it is: the model learns the offset of the centre from the crop and the object's size
/// against the crop, not the working volume's absolute positions.
pub(crate) fn crop_relative(translations: &Tensor, factors: &Tensor) -> Tensor {
    let x = translations.select(-1, 0);
    let y = translations.select(-1, 1);
    let z = translations.select(-1, 2).clamp_min(1e-3);
    let factor = |i: i64| factors.select(-1, i);
    let u = &x / &z * factor(0) + factor(1);
    let v = &y / &z * factor(2) + factor(3);
    let w = (z.log() + factor(4)) * 2.0;
    Tensor::stack(&[u, v, w], -1)
}

/// Per image `[B, 5]`: `2fx/s`, `2(cx + ½ − u₀)/s`, `2fy/s`, `2(cy + ½ − v₀)/s`,
/// `ln(s / (f · E))` for the reference extent `E` (mm), so that [`crop_relative`] is affine in
/// `x/z`, `y/z` and `ln z`.
pub(crate) fn crop_factors(
    geometry: &[CropGeometry],
    extent: f64,
    device: Device,
    kind: Kind,
) -> Tensor {
    per_crop::<{ FACTORS as usize }>(geometry, device, kind, |g| {
        let (k, c) = (&g.intrinsics, &g.crop);
        [
            2.0 * k.fx / c.side,
            2.0 * (k.cx + 0.5 - c.centre_x) / c.side,
            2.0 * k.fy / c.side,
            2.0 * (k.cy + 0.5 - c.centre_y) / c.side,
            (c.side / (g.focal() * extent)).ln(),
        ]
    })
}

/// What the image term learns about where the crop came from, `[B, 3]`: the direction of the
/// crop centre's ray ([`CropGeometry::ray`]'s `x` and `y`), and `ln(z_ref · s / (f · E))`, the
/// log-ratio of the depth at which the crop would be `E` mm wide to the working volume's middle
/// depth `z_ref` (0 for an object of the reference size there).
pub(crate) fn crop_features(
    geometry: &[CropGeometry],
    extent: f64,
    reference_depth: f64,
    device: Device,
    kind: Kind,
) -> Tensor {
    per_crop::<{ FEATURES as usize }>(geometry, device, kind, |g| {
        let ray = g.ray();
        [
            ray.x,
            ray.y,
            (reference_depth * g.crop.side / (g.focal() * extent)).ln(),
        ]
    })
}

/// `[B, N]` on `device` as `kind`: row `b` is `row` of crop `b`.
fn per_crop<const N: usize>(
    geometry: &[CropGeometry],
    device: Device,
    kind: Kind,
    row: impl Fn(&CropGeometry) -> [f64; N],
) -> Tensor {
    let values: Vec<f64> = geometry.iter().flat_map(row).collect();
    Tensor::from_slice(&values)
        .reshape([geometry.len() as i64, N as i64])
        .to_device(device)
        .to_kind(kind)
}

/// Translations as a `[N, 3]` float tensor (mm) on `device`.
pub fn translations_to_tensor(translations: &[Vector3<f64>], device: Device) -> Tensor {
    let values: Vec<f32> = translations
        .iter()
        .flat_map(|t| [t.x as f32, t.y as f32, t.z as f32])
        .collect();
    Tensor::from_slice(&values)
        .reshape([translations.len() as i64, 3])
        .to_device(device)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_point_on_the_crop_centre_ray_at_the_reference_extent_is_the_origin() {
        let geometry = CropGeometry {
            crop: CropBox {
                centre_x: 400.5,
                centre_y: 100.5,
                side: 80.0,
            },
            intrinsics: CameraIntrinsics {
                fx: 600.0,
                fy: 600.0,
                cx: 320.0,
                cy: 240.0,
            },
            width: 640,
            height: 480,
        };
        geometry.validate(0).unwrap();
        let extent = 100.0;
        // The crop is `extent` wide at z = f · E / s = 750 mm; its centre's ray there:
        let z = 750.0;
        let t = Vector3::new((400.0 - 320.0) * z / 600.0, (100.0 - 240.0) * z / 600.0, z);
        let factors = crop_factors(&[geometry], extent, Device::Cpu, Kind::Double);
        let q = crop_relative(
            &translations_to_tensor(&[t], Device::Cpu).to_kind(Kind::Double),
            &factors,
        );
        let q = Vec::<f64>::try_from(q.reshape([-1])).unwrap();
        assert!(q.iter().all(|v| v.abs() < 1e-4), "{q:?}");
        // Half a crop to the right, and twice as far: u = 1, w = 2 ln 2.
        let t = Vector3::new((440.0 - 320.0) * 2.0 * z / 600.0, t.y * 2.0, 2.0 * z);
        let q = crop_relative(
            &translations_to_tensor(&[t], Device::Cpu).to_kind(Kind::Double),
            &factors,
        );
        let q = Vec::<f64>::try_from(q.reshape([-1])).unwrap();
        assert!((q[0] - 1.0).abs() < 1e-4 && q[1].abs() < 1e-4, "{q:?}");
        assert!((q[2] - 2.0 * 2f64.ln()).abs() < 1e-4, "{q:?}");
        let features = crop_features(&[geometry], extent, z, Device::Cpu, Kind::Double);
        let features = Vec::<f64>::try_from(features.reshape([-1])).unwrap();
        assert!(features[2].abs() < 1e-12);
    }

    #[test]
    fn bad_geometry_is_refused_by_image() {
        let good = CropGeometry {
            crop: CropBox {
                centre_x: 10.0,
                centre_y: 10.0,
                side: 8.0,
            },
            intrinsics: CameraIntrinsics {
                fx: 100.0,
                fy: 100.0,
                cx: 10.0,
                cy: 10.0,
            },
            width: 20,
            height: 20,
        };
        good.validate(0).unwrap();
        let mut outside = good;
        outside.crop.centre_x = 25.0;
        let mut nan = good;
        nan.intrinsics.fx = f64::NAN;
        let mut flat = good;
        flat.crop.side = 0.0;
        for bad in [outside, nan, flat] {
            assert!(matches!(
                bad.validate(3),
                Err(ModelError::CropGeometry { image: 3, .. })
            ));
        }
    }
}
