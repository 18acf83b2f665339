//! The colour camera's image chain against closed forms: gains and the tone curve per pixel,
//! the noise's variance, the blur's spread, JPEG's loss.
use depth_render::{ImageChain, RenderError};
use proptest::prelude::*;

/// A `width × height` image of pseudo-random values (a fixed linear congruential sequence).
fn busy_image(width: u32, height: u32) -> Vec<[u8; 3]> {
    let mut state = 12345u32;
    (0..width * height)
        .map(|_| {
            std::array::from_fn(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (state >> 16) as u8
            })
        })
        .collect()
}

fn mean_and_variance(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let values: Vec<f64> = values.collect();
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / values.len() as f64;
    (mean, variance)
}

#[test]
fn the_identity_chain_changes_nothing() {
    let image = busy_image(31, 17);
    assert_eq!(
        ImageChain::IDENTITY.apply(&image, 31, 17, 5).unwrap(),
        image
    );
}

proptest! {
    /// Without noise, blur or JPEG each value is `round(255 · clamp(x · exposure · gain)^gamma)`
    /// with `x` the input over 255.
    #[test]
    fn gains_and_the_tone_curve_follow_their_formula(
        exposure in 0.3f32..2.0,
        gains in proptest::array::uniform3(0.7f32..1.3),
        gamma in 0.6f32..1.6,
        seed in any::<u64>(),
    ) {
        let chain = ImageChain { exposure, white_balance: gains, gamma, ..ImageChain::IDENTITY };
        let image = busy_image(9, 7);
        let out = chain.apply(&image, 9, 7, seed).unwrap();
        for (a, b) in image.iter().zip(&out) {
            for k in 0..3 {
                let x = f64::from(a[k]) / 255.0 * f64::from(exposure) * f64::from(gains[k]);
                let expected = 255.0 * x.clamp(0.0, 1.0).powf(f64::from(gamma));
                prop_assert!((f64::from(b[k]) - expected).abs() <= 0.51, "{} {}", b[k], expected);
            }
        }
    }
}

#[test]
fn the_noise_has_the_poisson_gaussian_variance() {
    // A flat grey of 0.4 full scale: variance shot · 0.4 + read² (Foi et al. 2008), in units of
    // full scale; 8-bit rounding adds 1/12 of a step squared.
    let (width, height) = (200, 150);
    let grey = vec![[102u8; 3]; width * height];
    let chain = ImageChain {
        shot_noise: 0.004,
        read_noise: 0.01,
        ..ImageChain::IDENTITY
    };
    let out = chain.apply(&grey, width as u32, height as u32, 3).unwrap();
    let (mean, variance) = mean_and_variance(out.iter().flatten().map(|&v| f64::from(v) / 255.0));
    let x = 102.0 / 255.0;
    let expected = 0.004 * x + 0.01f64.powi(2) + (1.0f64 / 255.0).powi(2) / 12.0;
    assert!((mean - x).abs() < 1e-3, "mean {mean}");
    assert!(
        (variance / expected - 1.0).abs() < 0.05,
        "{variance} {expected}"
    );
    // Seeded: the same seed gives the same image, another seed another.
    assert_eq!(
        chain.apply(&grey, width as u32, height as u32, 3).unwrap(),
        out
    );
    assert_ne!(
        chain.apply(&grey, width as u32, height as u32, 4).unwrap(),
        out
    );
}

#[test]
fn the_blur_spreads_a_line_by_its_sigma() {
    // A bright vertical line on a dark image: across it, the blurred profile's second moment is
    // σ² (a Gaussian kernel's) and its sum the line's. The 8-bit output loses the tails below
    // half a step, beyond 3σ here: a few per cent of the moment.
    let size = 41u32;
    let image: Vec<[u8; 3]> = (0..size * size)
        .map(|i| if i % size == 20 { [255; 3] } else { [0; 3] })
        .collect();
    let sigma = 2.0f32;
    let chain = ImageChain {
        blur_sigma: sigma,
        ..ImageChain::IDENTITY
    };
    let out = chain.apply(&image, size, size, 0).unwrap();
    let row = &out[(20 * size) as usize..(21 * size) as usize];
    let weight: Vec<f64> = row.iter().map(|p| f64::from(p[0])).collect();
    let total: f64 = weight.iter().sum();
    let moment: f64 = weight
        .iter()
        .enumerate()
        .map(|(x, w)| w * (x as f64 - 20.0).powi(2))
        .sum::<f64>()
        / total;
    assert!(
        (total / 255.0 - 1.0).abs() < 0.05,
        "total {}",
        total / 255.0
    );
    assert!(
        (moment / f64::from(sigma * sigma) - 1.0).abs() < 0.1,
        "{moment}"
    );
}

#[test]
fn jpeg_loses_more_at_lower_quality() {
    let (width, height) = (64u32, 48u32);
    // A smooth ramp with a sharp edge: what photographs hold.
    let image: Vec<[u8; 3]> = (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let edge = if x > 30 { 120 } else { 0 };
            [(x * 2 + edge) as u8, (y * 3) as u8, 90]
        })
        .collect();
    let error = |quality| {
        let chain = ImageChain {
            jpeg_quality: Some(quality),
            ..ImageChain::IDENTITY
        };
        let out = chain.apply(&image, width, height, 0).unwrap();
        image
            .iter()
            .flatten()
            .zip(out.iter().flatten())
            .map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs())
            .sum::<f64>()
            / (3 * width * height) as f64
    };
    let (fine, coarse) = (error(95), error(10));
    assert!(fine < 2.0, "quality 95: {fine}");
    assert!(coarse > 2.0 * fine, "quality 10: {coarse}, 95: {fine}");
}

#[test]
fn images_the_chain_cannot_process_are_refused() {
    let image = busy_image(4, 4);
    let refused = |chain: ImageChain, width| {
        matches!(
            chain.apply(&image, width, 4, 0),
            Err(RenderError::InvalidImage { .. })
        )
    };
    assert!(refused(ImageChain::IDENTITY, 5));
    let no_quality = ImageChain {
        jpeg_quality: Some(0),
        ..ImageChain::IDENTITY
    };
    assert!(refused(no_quality, 4));
    let negative = ImageChain {
        exposure: -1.0,
        ..ImageChain::IDENTITY
    };
    assert!(refused(negative, 4));
}
