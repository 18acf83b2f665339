//! Images as BOP stores them: depth as uint16 PNG in units of `depth_scale` mm, masks as 8-bit
//! PNG (255 on the object), colour as 8-bit RGB (PNG or JPEG). Writes are atomic (PNG only);
//! reads accept what the real BOP datasets ship.
use std::path::Path;

use image::{DynamicImage, ExtendedColorType, ImageEncoder, codecs::png::PngEncoder};

use crate::FileError;
use crate::atomic::write_atomically;

/// Writes z-depth in metres (0 = no measurement) as a uint16 PNG of `round(depth · 1000 /
/// depth_scale)`; fails when a depth does not fit in 16 bits at that scale.
pub fn write_depth(
    path: &Path,
    depth: &[f32],
    width: u32,
    height: u32,
    depth_scale: f64,
) -> Result<(), FileError> {
    let mut units = Vec::with_capacity(depth.len());
    for (i, &d) in depth.iter().enumerate() {
        let value = (f64::from(d) * 1e3 / depth_scale).round();
        if !(0.0..=65_535.0).contains(&value) {
            return Err(FileError::new(
                path,
                format!("pixel ({}, {})", i % width as usize, i / width as usize),
                format!("depth {d} m does not fit in uint16 at depth_scale {depth_scale}"),
            ));
        }
        units.push(value as u16);
    }
    let bytes: Vec<u8> = units.iter().flat_map(|v| v.to_ne_bytes()).collect();
    write_png(path, &bytes, width, height, ExtendedColorType::L16)
}

/// Writes an 8-bit RGB image.
pub fn write_rgb(path: &Path, rgb: &[[u8; 3]], width: u32, height: u32) -> Result<(), FileError> {
    write_png(
        path,
        rgb.as_flattened(),
        width,
        height,
        ExtendedColorType::Rgb8,
    )
}

/// Writes a mask as 8-bit grey: 255 where `mask` is true.
pub fn write_mask(path: &Path, mask: &[bool], width: u32, height: u32) -> Result<(), FileError> {
    let bytes: Vec<u8> = mask.iter().map(|&m| if m { 255 } else { 0 }).collect();
    write_png(path, &bytes, width, height, ExtendedColorType::L8)
}

fn write_png(
    path: &Path,
    bytes: &[u8],
    width: u32,
    height: u32,
    color: ExtendedColorType,
) -> Result<(), FileError> {
    write_atomically(path, |out| {
        PngEncoder::new(out)
            .write_image(bytes, width, height, color)
            .map_err(std::io::Error::other)
    })
}

/// The bounding box `[u0, v0, u1, v1]` (exclusive ends) of the true pixels of a row-major
/// mask of `width` columns, or `None` when none is true.
pub fn mask_box(mask: &[bool], width: usize) -> Option<[u32; 4]> {
    let width = width.max(1);
    let (mut low, mut high) = ([u32::MAX; 2], [0u32; 2]);
    for (i, _) in mask.iter().enumerate().filter(|&(_, &m)| m) {
        let p = [(i % width) as u32, (i / width) as u32];
        for axis in 0..2 {
            low[axis] = low[axis].min(p[axis]);
            high[axis] = high[axis].max(p[axis]);
        }
    }
    (low[0] <= high[0]).then(|| [low[0], low[1], high[0] + 1, high[1] + 1])
}

/// A decoded image of any BOP kind: its size and row-major pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Image<T> {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row-major pixels.
    pub pixels: Vec<T>,
}

fn decode(path: &Path) -> Result<DynamicImage, FileError> {
    image::ImageReader::open(path)
        .map_err(|e| FileError::new(path, "file", e.to_string()))?
        .with_guessed_format()
        .map_err(|e| FileError::new(path, "file", e.to_string()))?
        .decode()
        .map_err(|e| FileError::new(path, "file", format!("not a readable image: {e}")))
}

/// Reads a BOP depth image (16-bit grey PNG) as z-depth in metres: `value · depth_scale / 1000`,
/// 0 where the sensor had no reading.
pub fn read_depth(path: &Path, depth_scale: f64) -> Result<Image<f32>, FileError> {
    let DynamicImage::ImageLuma16(grey) = decode(path)? else {
        return Err(FileError::new(
            path,
            "pixel format",
            "expected a 16-bit greyscale depth image",
        ));
    };
    let metres_per_unit = depth_scale * 1e-3;
    Ok(Image {
        width: grey.width(),
        height: grey.height(),
        pixels: grey
            .pixels()
            .map(|p| (f64::from(p.0[0]) * metres_per_unit) as f32)
            .collect(),
    })
}

/// Reads a mask image: true where the pixel is not black (any bit depth or channel count).
pub fn read_mask(path: &Path) -> Result<Image<bool>, FileError> {
    let grey = decode(path)?.into_luma16();
    Ok(Image {
        width: grey.width(),
        height: grey.height(),
        pixels: grey.pixels().map(|p| p.0[0] > 0).collect(),
    })
}

/// Reads a colour image (PNG or JPEG, any bit depth) as 8-bit RGB.
pub fn read_rgb(path: &Path) -> Result<Image<[u8; 3]>, FileError> {
    let rgb = decode(path)?.into_rgb8();
    Ok(Image {
        width: rgb.width(),
        height: rgb.height(),
        pixels: rgb.pixels().map(|p| p.0).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_masks_and_colour_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let depth = [0.0f32, 0.5, 1.25, 6.5535];
        let path = dir.path().join("d.png");
        write_depth(&path, &depth, 2, 2, 0.1).unwrap();
        let back = read_depth(&path, 0.1).unwrap();
        assert_eq!((back.width, back.height), (2, 2));
        for (a, b) in depth.iter().zip(&back.pixels) {
            assert!((a - b).abs() < 1e-4, "{a} {b}");
        }
        let mask = [true, false, false, true];
        write_mask(&dir.path().join("m.png"), &mask, 2, 2).unwrap();
        assert_eq!(read_mask(&dir.path().join("m.png")).unwrap().pixels, mask);
        let rgb = [[1, 2, 3], [250, 0, 7], [0, 0, 0], [9, 9, 9]];
        write_rgb(&dir.path().join("c.png"), &rgb, 2, 2).unwrap();
        assert_eq!(read_rgb(&dir.path().join("c.png")).unwrap().pixels, rgb);
    }

    #[test]
    fn unreadable_and_wrong_kind_images_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let text = dir.path().join("x.png");
        std::fs::write(&text, "not an image").unwrap();
        assert_eq!(read_mask(&text).unwrap_err().field, "file");
        let rgb = dir.path().join("c.png");
        write_rgb(&rgb, &[[1, 2, 3]], 1, 1).unwrap();
        let error = read_depth(&rgb, 1.0).unwrap_err();
        assert_eq!(
            (error.path.as_path(), error.field.as_str()),
            (rgb.as_path(), "pixel format")
        );
        assert!(read_rgb(&dir.path().join("missing.png")).is_err());
    }
}

/// Whether the image file at `path` exists and ends as a whole PNG (its `IEND` chunk) or JPEG
/// (its end-of-image marker) ends: a cheap test, without decoding, for files that an
/// interrupted copy or a full disk truncated.
pub fn image_file_complete(path: &Path) -> bool {
    use std::io::{Read, Seek, SeekFrom};
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    let mut tail = [0u8; 12];
    if file.seek(SeekFrom::End(-12)).is_err() || file.read_exact(&mut tail).is_err() {
        return false;
    }
    &tail[4..8] == b"IEND" || tail[10..] == [0xFF, 0xD9]
}

#[cfg(test)]
mod completeness_tests {
    use super::*;

    #[test]
    fn a_truncated_or_missing_png_is_incomplete() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mask.png");
        assert!(!image_file_complete(&path));
        write_mask(&path, &[true, false, true, true], 2, 2).unwrap();
        assert!(image_file_complete(&path));
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
        assert!(!image_file_complete(&path));
    }
}
