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

/// A rectangle of an image in the continuous coordinates of [`CropBox`]: a detector's box, or
/// the bounding box of a mask's pixels. It selects the pixels whose centres lie inside it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImageBox {
    /// Left edge, pixels.
    pub x: f64,
    /// Top edge, pixels.
    pub y: f64,
    /// Width, pixels.
    pub width: f64,
    /// Height, pixels.
    pub height: f64,
}

impl ImageBox {
    /// The box of BOP's `[x, y, w, h]` (`bbox_visib`, `bbox_obj`), whose `w` and `h` are the
    /// last pixel's offsets from the first (the BOP toolkit's `calc_2d_bbox`: a box one pixel
    /// wide has `w` 0); `None` for BOP's empty box `[-1, -1, -1, -1]` or any negative entry.
    pub fn from_bop(bbox: [i64; 4]) -> Option<Self> {
        let [x, y, w, h] = bbox;
        (x >= 0 && y >= 0 && w >= 0 && h >= 0).then(|| Self {
            x: x as f64,
            y: y as f64,
            width: (w + 1) as f64,
            height: (h + 1) as f64,
        })
    }

    /// The bounding box of the non-zero pixels of `mask` (rows of `width`), `None` when it
    /// selects none.
    pub fn around(mask: &[u8], width: usize) -> Option<Self> {
        let (x0, y0, x1, y1) = mask_bounds(mask, width.max(1))?;
        Some(Self {
            x: x0 as f64,
            y: y0 as f64,
            width: (x1 - x0 + 1) as f64,
            height: (y1 - y0 + 1) as f64,
        })
    }

    /// Why the box cannot be cropped from a `width × height` image: not finite, empty or
    /// negative, or reaching outside the image; `None` when it can.
    pub fn problem(&self, width: usize, height: usize) -> Option<String> {
        let Self {
            x,
            y,
            width: w,
            height: h,
        } = *self;
        if ![x, y, w, h].iter().all(|v| v.is_finite()) {
            return Some(format!("{x},{y},{w},{h}: not finite numbers"));
        }
        if w < 1.0 || h < 1.0 {
            return Some(format!(
                "{x},{y},{w},{h}: the box is empty or negative (width and height need 1 pixel or more)"
            ));
        }
        if x < 0.0 || y < 0.0 || x + w > width as f64 || y + h > height as f64 {
            return Some(format!(
                "{x},{y},{w},{h}: the box reaches outside the {width} × {height} image \
                 (x in 0..{width} and y in 0..{height}, x + w ≤ {width}, y + h ≤ {height})"
            ));
        }
        None
    }

    /// The part of the box inside a `width × height` image (empty when none is).
    pub fn clipped(&self, width: usize, height: usize) -> Self {
        let (x0, y0) = (self.x.max(0.0), self.y.max(0.0));
        let x1 = (self.x + self.width).min(width as f64);
        let y1 = (self.y + self.height).min(height as f64);
        Self {
            x: x0,
            y: y0,
            width: (x1 - x0).max(0.0),
            height: (y1 - y0).max(0.0),
        }
    }

    /// The pixels of a `width × height` image whose centres lie inside the box, as a mask.
    pub fn mask(&self, width: usize, height: usize) -> Vec<u8> {
        let inside = |start: f64, length: f64, i: usize| {
            let centre = i as f64 + 0.5;
            start <= centre && centre < start + length
        };
        (0..width * height)
            .map(|i| {
                u8::from(
                    inside(self.x, self.width, i % width) && inside(self.y, self.height, i / width),
                )
            })
            .collect()
    }

    /// The square cut around the box: centred on it, its side the box's longer side plus the
    /// margin.
    pub fn square(&self, margin: f64) -> CropBox {
        CropBox {
            centre_x: self.x + self.width / 2.0,
            centre_y: self.y + self.height / 2.0,
            side: self.width.max(self.height) * (1.0 + margin),
        }
    }
}

/// The square [`crop_object`] cuts around the non-zero pixels of `mask` (`width × height`):
/// [`ImageBox::square`] of their bounding box.
pub fn crop_box(
    mask: &[u8],
    width: usize,
    height: usize,
    options: &CropOptions,
) -> Result<CropBox, ModelError> {
    check_mask(mask, width, height)?;
    check_options(options)?;
    let bounds = ImageBox::around(mask, width).ok_or(ModelError::EmptyMask)?;
    Ok(bounds.square(options.margin))
}

fn check_mask(mask: &[u8], width: usize, height: usize) -> Result<(), ModelError> {
    if width == 0 || height == 0 || mask.len() != width * height {
        return Err(ModelError::ImageShape {
            field: "mask",
            expected: format!("{width} × {height} = {} pixels", width * height),
            got: format!("{} pixels", mask.len()),
        });
    }
    Ok(())
}

fn check_options(options: &CropOptions) -> Result<(), ModelError> {
    if !(1..=4096).contains(&options.size) || !(0.0..=10.0).contains(&options.margin) {
        return Err(ModelError::option(
            "size",
            format!(
                "size {} and margin {}: need 1..=4096 and 0..=10",
                options.size, options.margin
            ),
        ));
    }
    Ok(())
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
    check_rgb(rgb, width, height)?;
    let square = crop_box(mask, width, height, options)?;
    Ok(resample(rgb, mask, width, height, &square, options.size))
}

/// The crop of `rgb` (as [`crop_object`]) in the square around `image_box`
/// ([`ImageBox::square`]): the pixels inside the box as they are, those outside it 0 — the
/// crop [`crop_object`] cuts for a mask that fills the box. Fails for a box
/// [`ImageBox::problem`] refuses.
pub fn crop_in_box(
    rgb: &[u8],
    image_box: &ImageBox,
    width: usize,
    height: usize,
    options: &CropOptions,
) -> Result<(Vec<f32>, CropBox), ModelError> {
    check_rgb(rgb, width, height)?;
    check_options(options)?;
    if let Some(problem) = image_box.problem(width, height) {
        return Err(ModelError::option("box", problem));
    }
    let mask = image_box.mask(width, height);
    let square = image_box.square(options.margin);
    Ok((
        resample(rgb, &mask, width, height, &square, options.size),
        square,
    ))
}

fn check_rgb(rgb: &[u8], width: usize, height: usize) -> Result<(), ModelError> {
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
    Ok(())
}

/// The `size × size` bilinear resampling of the pixels of `rgb` selected by `mask` in
/// `square`, channel-major in `[0, 1]` (0 off the mask or the image).
fn resample(
    rgb: &[u8],
    mask: &[u8],
    width: usize,
    height: usize,
    square: &CropBox,
    size: usize,
) -> Vec<f32> {
    let CropBox {
        centre_x,
        centre_y,
        side,
    } = *square;
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
    out
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

    proptest::proptest! {
        /// A box crop is the crop of the mask that fills the box (the mask drawn here pixel by
        /// pixel from the integer box), with the same square.
        #[test]
        fn a_box_crops_as_the_mask_that_fills_it(
            (width, height) in (4usize..40, 4usize..40),
            corner in (0.0f64..1.0, 0.0f64..1.0),
            extent in (0.0f64..1.0, 0.0f64..1.0),
            size in 2usize..24,
            seed in 0u64..1000,
        ) {
            let x = (corner.0 * (width - 1) as f64) as usize;
            let y = (corner.1 * (height - 1) as f64) as usize;
            let w = 1 + (extent.0 * (width - x - 1) as f64) as usize;
            let h = 1 + (extent.1 * (height - y - 1) as f64) as usize;
            let rgb: Vec<u8> = (0..width * height * 3)
                .map(|i| ((i as u64 * 2_654_435_761 + seed) % 251) as u8)
                .collect();
            let mut mask = vec![0u8; width * height];
            for row in y..y + h {
                for col in x..x + w {
                    mask[row * width + col] = 1;
                }
            }
            let options = CropOptions::new(size);
            let image_box = ImageBox { x: x as f64, y: y as f64, width: w as f64, height: h as f64 };
            let (from_box, square) = crop_in_box(&rgb, &image_box, width, height, &options).unwrap();
            proptest::prop_assert_eq!(square, crop_box(&mask, width, height, &options).unwrap());
            proptest::prop_assert_eq!(from_box, crop_object(&rgb, &mask, width, height, &options).unwrap());
            proptest::prop_assert_eq!(ImageBox::around(&mask, width), Some(image_box));
        }
    }

    #[test]
    fn boxes_follow_bop_and_bad_ones_are_refused() {
        // BOP's `w` and `h` are the last pixel's offsets: [3, 4, 0, 0] is the pixel (3, 4).
        let one = ImageBox::from_bop([3, 4, 0, 0]).unwrap();
        let mask = one.mask(8, 8);
        assert_eq!(mask.iter().map(|&m| usize::from(m)).sum::<usize>(), 1);
        assert_eq!(mask[4 * 8 + 3], 1);
        assert_eq!(ImageBox::from_bop([-1, -1, -1, -1]), None);
        let problem = |x, y, width, height| {
            ImageBox {
                x,
                y,
                width,
                height,
            }
            .problem(640, 480)
        };
        assert_eq!(problem(0.0, 0.0, 640.0, 480.0), None);
        for (bad, words) in [
            ((10.0, 10.0, 0.0, 5.0), "empty"),
            ((10.0, 10.0, -4.0, 5.0), "negative"),
            ((-1.0, 10.0, 20.0, 5.0), "outside"),
            ((630.0, 10.0, 20.0, 5.0), "outside"),
            ((10.0, 10.0, f64::NAN, 5.0), "finite"),
        ] {
            let reason = problem(bad.0, bad.1, bad.2, bad.3).unwrap();
            assert!(reason.contains(words), "{bad:?}: {reason}");
        }
        let rgb = vec![0u8; 640 * 480 * 3];
        let outside = ImageBox {
            x: 700.0,
            y: 0.0,
            width: 10.0,
            height: 10.0,
        };
        assert!(matches!(
            crop_in_box(&rgb, &outside, 640, 480, &CropOptions::new(8)),
            Err(ModelError::InvalidOption { name: "box", .. })
        ));
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
