//! The network's input: a square RGB crop around an object's mask, background set to 0.
use serde::{Deserialize, Serialize};
use tch::Tensor;

use crate::ModelError;

/// The square a crop was cut from ([`crate::crop_box`]), in continuous image coordinates where
/// pixel `(i, j)` covers `[i, i + 1) × [j, j + 1)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CropBox {
    /// Centre `x`, pixels.
    pub centre_x: f64,
    /// Centre `y`, pixels.
    pub centre_y: f64,
    /// Side, pixels.
    pub side: f64,
}

/// How a crop is cut out of an image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CropOptions {
    /// Side of the output square, in pixels.
    pub size: usize,
    /// Border added around the mask's bounding box, as a fraction of its longer side.
    pub margin: f64,
}

impl CropOptions {
    /// A `size × size` crop with a 10% margin.
    pub const fn new(size: usize) -> Self {
        Self { size, margin: 0.1 }
    }
}

/// The square [`crop_object`] cuts around the non-zero pixels of `mask` (`width × height`):
/// centred on the mask's bounding box, its side the box's longer side plus the margin.
pub fn crop_box(
    mask: &[u8],
    width: usize,
    height: usize,
    options: &CropOptions,
) -> Result<CropBox, ModelError> {
    if width == 0 || height == 0 || mask.len() != width * height {
        return Err(ModelError::ImageShape {
            field: "mask",
            expected: format!("{width} × {height} = {} pixels", width * height),
            got: format!("{} pixels", mask.len()),
        });
    }
    if !(1..=4096).contains(&options.size) || !(0.0..=10.0).contains(&options.margin) {
        return Err(ModelError::option(
            "size",
            format!(
                "size {} and margin {}: need 1..=4096 and 0..=10",
                options.size, options.margin
            ),
        ));
    }
    let (x0, y0, x1, y1) = mask_bounds(mask, width).ok_or(ModelError::EmptyMask)?;
    Ok(CropBox {
        centre_x: (x0 + x1 + 1) as f64 / 2.0,
        centre_y: (y0 + y1 + 1) as f64 / 2.0,
        side: ((x1 - x0 + 1).max(y1 - y0 + 1)) as f64 * (1.0 + options.margin),
    })
}

/// The inclusive bounding box `(x0, y0, x1, y1)` of the non-zero pixels of `mask` (rows of
/// `width`), or `None` when there are none; row by row, each row's first and last set pixel.
fn mask_bounds(mask: &[u8], width: usize) -> Option<(usize, usize, usize, usize)> {
    let mut bounds: Option<(usize, usize, usize, usize)> = None;
    for (y, row) in mask.chunks_exact(width).enumerate() {
        let Some(first) = row.iter().position(|&m| m != 0) else {
            continue;
        };
        let last = row.iter().rposition(|&m| m != 0).unwrap_or(first);
        bounds = Some(match bounds {
            None => (first, y, last, y),
            Some((x0, y0, x1, _)) => (x0.min(first), y0, x1.max(last), y),
        });
    }
    bounds
}

/// The crop of `rgb` (interleaved 8-bit RGB, `width × height`, row-major) in the square of
/// [`crop_box`] around the non-zero pixels of `mask` (`width × height`), resampled bilinearly
/// to `size × size`. Pixels off the mask or off the image are 0. Returns `[3, size, size]`
/// values in `[0, 1]`, channel-major.
pub fn crop_object(
    rgb: &[u8],
    mask: &[u8],
    width: usize,
    height: usize,
    options: &CropOptions,
) -> Result<Vec<f32>, ModelError> {
    if width == 0 || height == 0 || rgb.len() != width * height * 3 {
        return Err(ModelError::ImageShape {
            field: "rgb",
            expected: format!(
                "{width} × {height} × 3 = {} bytes (8-bit RGB)",
                width * height * 3
            ),
            got: format!("{} bytes", rgb.len()),
        });
    }
    let CropBox {
        centre_x,
        centre_y,
        side,
    } = crop_box(mask, width, height, options)?;
    let size = options.size;
    let scale = side / size as f64;
    let plane = size * size;
    let mut out = vec![0.0f32; 3 * plane];
    let sample = |x: isize, y: isize, channel: usize| -> f32 {
        if x < 0 || y < 0 || x as usize >= width || y as usize >= height {
            return 0.0;
        }
        let i = y as usize * width + x as usize;
        if mask[i] == 0 {
            0.0
        } else {
            rgb[3 * i + channel] as f32 / 255.0
        }
    };
    for row in 0..size {
        let v = centre_y - side / 2.0 + (row as f64 + 0.5) * scale - 0.5;
        let (ry, fy) = (v.floor() as isize, (v - v.floor()) as f32);
        for col in 0..size {
            let u = centre_x - side / 2.0 + (col as f64 + 0.5) * scale - 0.5;
            let (rx, fx) = (u.floor() as isize, (u - u.floor()) as f32);
            for channel in 0..3 {
                let top = sample(rx, ry, channel) * (1.0 - fx) + sample(rx + 1, ry, channel) * fx;
                let bottom =
                    sample(rx, ry + 1, channel) * (1.0 - fx) + sample(rx + 1, ry + 1, channel) * fx;
                out[channel * plane + row * size + col] = top * (1.0 - fy) + bottom * fy;
            }
        }
    }
    Ok(out)
}

/// Crops from [`crop_object`] stacked into a `[B, 3, S, S]` float tensor on the CPU.
pub fn crops_to_tensor(crops: &[Vec<f32>], size: usize) -> Result<Tensor, ModelError> {
    let plane = 3 * size * size;
    if let Some(i) = crops.iter().position(|c| c.len() != plane) {
        return Err(ModelError::ImageShape {
            field: "crops",
            expected: format!("3 × {size} × {size} = {plane} values per crop"),
            got: format!("{} values in crop {i}", crops[i].len()),
        });
    }
    let flat: Vec<f32> = crops.concat();
    Ok(Tensor::from_slice(&flat).reshape([crops.len() as i64, 3, size as i64, size as i64]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crop_centres_the_object_and_blanks_the_background() {
        let (width, height) = (40, 30);
        let mut rgb = vec![0u8; width * height * 3];
        let mut mask = vec![0u8; width * height];
        for y in 10..20 {
            for x in 5..15 {
                let i = y * width + x;
                mask[i] = 1;
                rgb[3 * i] = 255;
            }
        }
        // A bright pixel off the mask must not leak in.
        rgb[3 * (10 * width + 16) + 1] = 255;
        let crop = crop_object(
            &rgb,
            &mask,
            width,
            height,
            &CropOptions {
                size: 20,
                margin: 0.0,
            },
        )
        .unwrap();
        assert!((crop[10 * 20 + 10] - 1.0).abs() < 1e-6, "centre is red");
        assert!(
            crop[20 * 20..].iter().all(|&v| v == 0.0),
            "green and blue are 0"
        );
        let red_fraction = crop[..400].iter().sum::<f32>() / 400.0;
        assert!(
            red_fraction > 0.8,
            "the mask fills the crop: {red_fraction}"
        );
    }

    proptest::proptest! {
        /// The row-by-row bounds are the bounding box of the set pixels.
        #[test]
        fn mask_bounds_are_the_bounding_box_of_the_set_pixels(
            width in 1usize..12,
            bits in proptest::collection::vec(0u8..4, 1..120),
        ) {
            // Sparse masks: about a quarter of the pixels set.
            let mask: Vec<u8> = bits.iter().map(|&b| u8::from(b == 0)).collect();
            let mask = &mask[..mask.len() / width * width];
            let set: Vec<(usize, usize)> = (0..mask.len())
                .filter(|&i| mask[i] != 0)
                .map(|i| (i % width, i / width))
                .collect();
            let expected = (!set.is_empty()).then(|| {
                let xs = set.iter().map(|p| p.0);
                let ys = set.iter().map(|p| p.1);
                (xs.clone().min().unwrap(), ys.clone().min().unwrap(), xs.max().unwrap(), ys.max().unwrap())
            });
            proptest::prop_assert_eq!(mask_bounds(mask, width), expected);
        }
    }

    #[test]
    fn crop_rejects_bad_buffers_and_empty_masks() {
        let rgb = vec![0u8; 4 * 4 * 3];
        let mask = vec![0u8; 16];
        let options = CropOptions::new(8);
        assert!(matches!(
            crop_object(&rgb, &mask, 4, 4, &options),
            Err(ModelError::EmptyMask)
        ));
        assert!(matches!(
            crop_object(&rgb[..40], &mask, 4, 4, &options),
            Err(ModelError::ImageShape { field: "rgb", .. })
        ));
        assert!(matches!(
            crop_object(&rgb, &mask[..15], 4, 4, &options),
            Err(ModelError::ImageShape { field: "mask", .. })
        ));
    }
}
