//! Training-time image augmentation: occlusion rectangles (as in the pseudo-label paper) and
//! mild colour jitter, drawn from a caller's seeded generator.
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor};

/// What [`augment`] does to a batch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Augmentation {
    /// Fraction of the images that get an occluding rectangle (0.8 in the paper; 0 disables).
    pub occlusion_probability: f64,
    /// Range of the rectangle's area as a fraction of the crop (`[0.1, 0.5]` in the paper).
    pub occlusion_area: [f64; 2],
    /// Colour jitter strength `j`: brightness × U(1 − j, 1 + j) per image and a gain
    /// × U(1 − j/2, 1 + j/2) per channel (0 disables).
    pub colour_jitter: f64,
}

impl Augmentation {
    /// No augmentation.
    pub const NONE: Self = Self {
        occlusion_probability: 0.0,
        occlusion_area: [0.1, 0.5],
        colour_jitter: 0.0,
    };

    /// Colour jitter only (`j = 0.1`).
    pub const COLOUR: Self = Self {
        colour_jitter: 0.1,
        ..Self::NONE
    };

    /// The paper's occlusion (80% of images, 10–50% of the crop) plus colour jitter.
    pub const OCCLUSION: Self = Self {
        occlusion_probability: 0.8,
        ..Self::COLOUR
    };

    /// Whether it changes anything.
    pub fn is_identity(&self) -> bool {
        self.occlusion_probability <= 0.0 && self.colour_jitter <= 0.0
    }
}

impl Default for Augmentation {
    fn default() -> Self {
        Self::COLOUR
    }
}

/// `images` (`[B, 3, S, S]` in `[0, 1]`) with occluded rectangles set to 0 (the masked
/// background) and colours jittered, clamped to `[0, 1]`.
pub fn augment<R: Rng + ?Sized>(images: &Tensor, options: &Augmentation, rng: &mut R) -> Tensor {
    if options.is_identity() {
        return images.shallow_clone();
    }
    let size = images.size();
    let (batch, side) = (size[0] as usize, size[2] as usize);
    let mut keep = vec![1.0f32; batch * side * side];
    let mut gains = vec![1.0f32; batch * 3];
    for (plane, gain) in keep.chunks_mut(side * side).zip(gains.chunks_mut(3)) {
        if rng.random_bool(options.occlusion_probability.clamp(0.0, 1.0)) {
            occlude(plane, side, options.occlusion_area, rng);
        }
        if options.colour_jitter > 0.0 {
            let j = options.colour_jitter;
            let brightness = rng.random_range(1.0 - j..1.0 + j);
            for g in gain.iter_mut() {
                *g = (brightness * rng.random_range(1.0 - j / 2.0..1.0 + j / 2.0)) as f32;
            }
        }
    }
    let device = images.device();
    let keep = Tensor::from_slice(&keep)
        .reshape([batch as i64, 1, side as i64, side as i64])
        .to_device(device);
    let gains = Tensor::from_slice(&gains)
        .reshape([batch as i64, 3, 1, 1])
        .to_device(device);
    (images.to_kind(Kind::Float) * keep * gains).clamp(0.0, 1.0)
}

/// Zeroes one axis-aligned rectangle of `plane` (`side × side`) with an area fraction uniform in
/// `area` and an aspect ratio log-uniform in [1/3, 3].
fn occlude<R: Rng + ?Sized>(plane: &mut [f32], side: usize, area: [f64; 2], rng: &mut R) {
    let (low, high) = (area[0].clamp(0.0, 1.0), area[1].clamp(0.0, 1.0));
    let fraction = if high > low {
        rng.random_range(low..high)
    } else {
        low
    };
    let aspect = rng.random_range((1.0f64 / 3.0).ln()..3.0f64.ln()).exp();
    let s = side as f64;
    let width = ((fraction * aspect).sqrt() * s).round().clamp(1.0, s) as usize;
    let height = ((fraction / aspect).sqrt() * s).round().clamp(1.0, s) as usize;
    let x0 = rng.random_range(0..=side - width);
    let y0 = rng.random_range(0..=side - height);
    for row in plane.chunks_mut(side).skip(y0).take(height) {
        row[x0..x0 + width].fill(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn occlusion_covers_the_requested_area_of_most_images() {
        let images = Tensor::ones([200, 3, 32, 32], (Kind::Float, tch::Device::Cpu));
        let options = Augmentation {
            colour_jitter: 0.0,
            ..Augmentation::OCCLUSION
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let out = augment(&images, &options, &mut rng);
        let covered = Vec::<f32>::try_from((out.select(1, 0).neg() + 1.0).mean_dim(
            [1, 2].as_slice(),
            false,
            Kind::Float,
        ))
        .unwrap();
        let occluded = covered.iter().filter(|&&c| c > 0.0).count();
        assert!(
            (140..=180).contains(&occluded),
            "{occluded} of 200 occluded"
        );
        // Rounding to whole pixels and clamping very elongated rectangles widen the range.
        assert!(
            covered
                .iter()
                .all(|&c| c == 0.0 || (0.05..=0.6).contains(&c))
        );
    }

    #[test]
    fn jitter_stays_in_range_and_keeps_the_background() {
        let base = Tensor::full([8, 3, 16, 16], 0.9, (Kind::Float, tch::Device::Cpu));
        let _ = base.narrow(3, 0, 8).zero_();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let out = augment(&base, &Augmentation::COLOUR, &mut rng);
        assert!(f64::try_from(out.max()).unwrap() <= 1.0);
        assert_eq!(f64::try_from(out.narrow(3, 0, 8).abs().max()).unwrap(), 0.0);
        assert!(f64::try_from((&out - &base).abs().max()).unwrap() > 0.01);
    }
}
