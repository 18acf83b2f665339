//! Figures as PNG images, drawn without system fonts: the Implicit-PDF visualisation of a
//! distribution over SO(3) ([`plot_distribution`]) and a run's training curves
//! ([`plot_training_curves`]).
mod canvas;
mod curves;
mod distribution;

pub use canvas::{Canvas, hue};
pub use curves::{plot_training_curves, read_train_log};
pub use distribution::plot_distribution;

/// Writes `image` as a PNG atomically.
pub fn write_png(
    path: &std::path::Path,
    image: &image::RgbImage,
) -> Result<(), bop_dataset::FileError> {
    let pixels: Vec<[u8; 3]> = image.pixels().map(|p| p.0).collect();
    bop_dataset::write_rgb(path, &pixels, image.width(), image.height())
}
