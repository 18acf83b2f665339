//! Training-time image augmentation: occlusion rectangles (as in the pseudo-label paper), mild
//! colour jitter and a Gaussian blur, drawn from a caller's seeded generator.
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
    /// Fraction of the images blurred (0 disables), each by a Gaussian of σ uniform in
    /// `(0, blur_sigma]` pixels of the crop: a real camera's focus and motion blur.
    #[serde(default)]
    pub blur_probability: f64,
    /// Largest σ of the blur (crop pixels).
    #[serde(default)]
    pub blur_sigma: f64,
}

impl Augmentation {
    /// No augmentation.
    pub const NONE: Self = Self {
        occlusion_probability: 0.0,
        occlusion_area: [0.1, 0.5],
        colour_jitter: 0.0,
        blur_probability: 0.0,
        blur_sigma: 0.0,
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
        self.occlusion_probability <= 0.0 && self.colour_jitter <= 0.0 && !self.blurs()
    }

    fn blurs(&self) -> bool {
        self.blur_probability > 0.0 && self.blur_sigma > 0.0
    }
}

impl Default for Augmentation {
    fn default() -> Self {
        Self::COLOUR
    }
}

/// `images` (`[B, 3, S, S]` in `[0, 1]`) with occluded rectangles set to 0 (the masked
/// background), colours jittered and some blurred, clamped to `[0, 1]`. Without blur, the
/// generator is drawn from as before blur existed.
pub fn augment<R: Rng + ?Sized>(images: &Tensor, options: &Augmentation, rng: &mut R) -> Tensor {
    if options.is_identity() {
        return images.shallow_clone();
    }
    let size = images.size();
    let (batch, side) = (size[0] as usize, size[2] as usize);
    let mut keep = vec![1.0f32; batch * side * side];
    let mut gains = vec![1.0f32; batch * 3];
    let mut blurs = Vec::new();
    for (i, (plane, gain)) in keep
        .chunks_mut(side * side)
        .zip(gains.chunks_mut(3))
        .enumerate()
    {
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
        if options.blurs() && rng.random_bool(options.blur_probability.clamp(0.0, 1.0)) {
            blurs.push((i as i64, rng.random_range(0.0..options.blur_sigma)));
        }
    }
    let device = images.device();
    let keep = Tensor::from_slice(&keep)
        .reshape([batch as i64, 1, side as i64, side as i64])
        .to_device(device);
    let gains = Tensor::from_slice(&gains)
        .reshape([batch as i64, 3, 1, 1])
        .to_device(device);
    let mut out = images.to_kind(Kind::Float);
    if !blurs.is_empty() {
        // Each blurred image on its own (their σ differ), put back into the batch at once.
        let blurred: Vec<Tensor> = blurs
            .iter()
            .map(|&(i, sigma)| gaussian_blur(&out.narrow(0, i, 1), sigma))
            .collect();
        let rows: Vec<i64> = blurs.iter().map(|&(i, _)| i).collect();
        let rows = Tensor::from_slice(&rows).to_device(device);
        out = out.index_copy(0, &rows, &Tensor::cat(&blurred, 0));
    }
    (out * keep * gains).clamp(0.0, 1.0)
}

/// `image` (`[1, C, S, S]`) convolved with a normalised Gaussian of `sigma` pixels, truncated
/// at 3σ (and at the image's size), zero outside the image (the masked background).
fn gaussian_blur(image: &Tensor, sigma: f64) -> Tensor {
    let size = image.size();
    let (channels, side) = (size[1], size[2]);
    let radius = ((3.0 * sigma).ceil() as i64).clamp(1, (side - 1).max(1));
    let taps: Vec<f32> = (-radius..=radius)
        .map(|x| (-((x * x) as f64) / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = taps.iter().sum();
    let n = taps.len() as i64;
    let row = Tensor::from_slice(&taps.iter().map(|t| t / total).collect::<Vec<_>>())
        .to_device(image.device());
    let along = |t: &Tensor, shape: [i64; 4], padding: [i64; 2]| {
        let weight = row.reshape(shape).repeat([channels, 1, 1, 1]);
        t.conv2d(&weight, None::<Tensor>, [1, 1], padding, [1, 1], channels)
    };
    let horizontal = along(image, [1, 1, 1, n], [0, radius]);
    along(&horizontal, [1, 1, n, 1], [radius, 0])
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

    #[test]
    fn blur_spreads_a_point_by_sigma_and_keeps_its_mass() {
        // A point in the middle of a 41² image: blurred, its mass stays 1 and its second
        // moment along each axis is σ² (a Gaussian's), the kernel being wide enough (3σ).
        let mut point = vec![0.0f32; 3 * 41 * 41];
        for c in 0..3 {
            point[c * 41 * 41 + 20 * 41 + 20] = 1.0;
        }
        let image = Tensor::from_slice(&point).reshape([1, 3, 41, 41]);
        let sigma = 1.7;
        let out = gaussian_blur(&image, sigma);
        assert_eq!(out.size(), vec![1, 3, 41, 41]);
        let red = Vec::<f32>::try_from(out.select(1, 0).flatten(0, -1)).unwrap();
        let mass: f64 = red.iter().map(|&v| f64::from(v)).sum();
        let moment = |axis: usize| -> f64 {
            red.iter()
                .enumerate()
                .map(|(i, &v)| {
                    let d = [i % 41, i / 41][axis] as f64 - 20.0;
                    f64::from(v) * d * d
                })
                .sum()
        };
        assert!((mass - 1.0).abs() < 1e-5, "{mass}");
        for axis in 0..2 {
            assert!(
                (moment(axis) / (sigma * sigma) - 1.0).abs() < 0.02,
                "{}",
                moment(axis)
            );
        }
    }

    #[test]
    fn blur_touches_the_share_asked_for_and_nothing_else_without_it() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let images = Tensor::rand([100, 3, 12, 12], (Kind::Float, tch::Device::Cpu));
        let options = Augmentation {
            blur_probability: 0.5,
            blur_sigma: 1.5,
            ..Augmentation::NONE
        };
        let out = augment(&images, &options, &mut rng);
        let changed =
            Vec::<f32>::try_from((&out - &images).abs().amax([1, 2, 3].as_slice(), false))
                .unwrap()
                .iter()
                .filter(|&&d| d > 1e-6)
                .count();
        // Half of 100: binomial sd 5.
        assert!((35..=65).contains(&changed), "{changed} blurred");
        // Without blur the generator is drawn from as before: colour jitter alone leaves it
        // where colour jitter with a blur of probability 0 does.
        let (mut a, mut b) = (ChaCha8Rng::seed_from_u64(6), ChaCha8Rng::seed_from_u64(6));
        let no_blur = Augmentation {
            blur_sigma: 2.0,
            ..Augmentation::COLOUR
        };
        let _ = augment(&images, &Augmentation::COLOUR, &mut a);
        let _ = augment(&images, &no_blur, &mut b);
        assert_eq!(a.random::<u64>(), b.random::<u64>());
    }
}
