//! Figures as PNG images, drawn with plotters and an embedded font (no system font needed): the
//! Implicit-PDF visualisation of a distribution over SO(3) ([`plot_distribution`]), a run's
//! training curves ([`plot_training_curves`]), the errors of pseudo labels
//! ([`plot_label_errors`]) and a distribution over translations ([`plot_translation`]).
mod curves;
mod distribution;
mod label_errors;
mod style;
mod translation;

pub use curves::{plot_training_curves, read_train_log};
pub use distribution::plot_distribution;
pub use label_errors::plot_label_errors;
pub use style::hue;
pub use translation::plot_translation;

/// Writes `image` as a PNG atomically.
pub fn write_png(
    path: &std::path::Path,
    image: &image::RgbImage,
) -> Result<(), bop_dataset::FileError> {
    let pixels: Vec<[u8; 3]> = image.pixels().map(|p| p.0).collect();
    bop_dataset::write_rgb(path, &pixels, image.width(), image.height())
}
