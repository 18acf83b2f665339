//! What a colour camera makes of the light reaching it, in the order it happens: a focus blur,
//! exposure and white-balance gains, signal-dependent noise (the Poisson–Gaussian model of Foi
//! et al. 2008: variance `shot · x + read²` for a linear value `x ∈ [0, 1]`), a tone curve
//! (`x^gamma`), 8-bit quantisation and a JPEG round trip. The colour counterpart of
//! [`crate::DepthSensor`]; randomised per frame, it is part of the domain randomisation that lets
//! a network trained on renders read real camera images.
use image::RgbImage;
use image::codecs::jpeg::JpegEncoder;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::RenderError;
use crate::sensor::gaussians;

/// One camera's image chain (see the module's documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageChain {
    /// Standard deviation of a Gaussian blur, in pixels (0: sharp).
    pub blur_sigma: f32,
    /// Gain on every channel (1: as rendered).
    pub exposure: f32,
    /// Gains of the red, green and blue channels (white balance).
    pub white_balance: [f32; 3],
    /// Shot noise: the variance per unit of signal (0: none).
    pub shot_noise: f32,
    /// Read noise: a standard deviation in units of full scale (0: none).
    pub read_noise: f32,
    /// Exponent of the tone curve on values in `[0, 1]` (1: none).
    pub gamma: f32,
    /// Quality (1–100) of a JPEG compression and decompression, or none.
    pub jpeg_quality: Option<u8>,
}

impl ImageChain {
    /// The chain that changes nothing.
    pub const IDENTITY: Self = Self {
        blur_sigma: 0.0,
        exposure: 1.0,
        white_balance: [1.0; 3],
        shot_noise: 0.0,
        read_noise: 0.0,
        gamma: 1.0,
        jpeg_quality: None,
    };

    /// What the camera records of the row-major 8-bit image `rgb` (`width × height`); the
    /// noise is drawn from `seed`.
    ///
    /// Errors: a pixel count other than `width × height`, a JPEG quality outside 1–100, or a
    /// gain, noise or exponent that is negative or not finite.
    pub fn apply(
        &self,
        rgb: &[[u8; 3]],
        width: u32,
        height: u32,
        seed: u64,
    ) -> Result<Vec<[u8; 3]>, RenderError> {
        self.check(rgb.len(), width, height)?;
        let pixels: Vec<u8> = rgb.iter().flatten().copied().collect();
        let mut image = RgbImage::from_raw(width, height, pixels).ok_or_else(|| invalid("size"))?;
        if self.blur_sigma > 0.0 {
            image = image::imageops::blur(&image, self.blur_sigma);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut noise = [0.0f32; 4];
        for (i, value) in image.iter_mut().enumerate() {
            let channel = i % 3;
            if i % 4 == 0 {
                noise = gaussians(&mut rng);
            }
            let x = f32::from(*value) / 255.0 * self.exposure * self.white_balance[channel];
            let sd = (self.shot_noise * x.max(0.0) + self.read_noise * self.read_noise).sqrt();
            let x = (x + sd * noise[i % 4]).clamp(0.0, 1.0).powf(self.gamma);
            *value = (x * 255.0).round() as u8;
        }
        if let Some(quality) = self.jpeg_quality {
            image = jpeg_round_trip(&image, quality)?;
        }
        Ok(image.pixels().map(|p| p.0).collect())
    }

    fn check(&self, pixels: usize, width: u32, height: u32) -> Result<(), RenderError> {
        if pixels != width as usize * height as usize {
            return Err(invalid(&format!("{pixels} pixels for {width}×{height}")));
        }
        let numbers = [
            self.blur_sigma,
            self.exposure,
            self.shot_noise,
            self.read_noise,
            self.gamma,
        ];
        if numbers
            .iter()
            .chain(&self.white_balance)
            .any(|v| !v.is_finite() || *v < 0.0)
        {
            return Err(invalid(
                "a gain, noise or exponent is negative or not finite",
            ));
        }
        if self.jpeg_quality.is_some_and(|q| !(1..=100).contains(&q)) {
            return Err(invalid("JPEG quality outside 1–100"));
        }
        Ok(())
    }
}

/// The image after JPEG compression at `quality` and decompression.
fn jpeg_round_trip(image: &RgbImage, quality: u8) -> Result<RgbImage, RenderError> {
    let mut bytes = Vec::new();
    JpegEncoder::new_with_quality(&mut bytes, quality)
        .encode_image(image)
        .map_err(|e| invalid(&format!("JPEG encoding: {e}")))?;
    let decoded = image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)
        .map_err(|e| invalid(&format!("JPEG decoding: {e}")))?;
    Ok(decoded.into_rgb8())
}

fn invalid(reason: &str) -> RenderError {
    RenderError::InvalidImage {
        reason: reason.into(),
    }
}
