//! PNG images as BOP stores them: depth as uint16 in units of `depth_scale` mm, masks as 8-bit
//! (255 on the object), colour as 8-bit RGB. Writes are atomic.
use std::path::Path;

use image::{ExtendedColorType, ImageEncoder, codecs::png::PngEncoder};

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
            .map_err(anyhow::Error::from)
    })
    .map_err(|e| FileError::new(path, "file", format!("{e:#}")))
}
