//! What every figure shares: the font (DejaVu Sans, embedded by the `dejavu` crate and
//! registered with plotters once per process, so no system font is needed), a white RGB
//! canvas turned into an image, the hue wheel and the error of drawing.
use std::sync::OnceLock;

use image::RgbImage;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::Error;

/// The font family every text of the figures uses.
pub const FONT: &str = "sans-serif";

/// Registers DejaVu Sans (regular and bold) as [`FONT`] with plotters, once.
fn register_fonts() -> Result<(), Error> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
            && register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Figure("the embedded font cannot be read".into()))
    }
}

/// A drawing error as a [`Error::Figure`].
pub fn figure_error(error: impl std::fmt::Display) -> Error {
    Error::Figure(error.to_string())
}

/// Draws a `width × height` figure on a white canvas with `draw`, and returns it as an image.
pub fn draw_figure(
    width: u32,
    height: u32,
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), Error>,
) -> Result<RgbImage, Error> {
    register_fonts()?;
    let mut buffer = vec![255u8; 3 * width as usize * height as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        draw(&root)?;
        root.present().map_err(figure_error)?;
    }
    RgbImage::from_raw(width, height, buffer)
        .ok_or_else(|| Error::Figure("canvas of the wrong size".into()))
}

/// A fully saturated colour of hue `h` (turns; any real number wraps), as matplotlib's `hsv`
/// colour map: the cyclic colour of a rotation about an axis.
pub fn hue(h: f64) -> RGBColor {
    let h = h.rem_euclid(1.0) * 6.0;
    let x = 1.0 - (h % 2.0 - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    let byte = |v: f64| (v * 255.0).round() as u8;
    RGBColor(byte(r), byte(g), byte(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hue_wheel_is_cyclic_and_saturated() {
        assert_eq!(hue(0.0), RGBColor(255, 0, 0));
        assert_eq!(hue(1.0 / 3.0), RGBColor(0, 255, 0));
        assert_eq!(hue(2.0 / 3.0), RGBColor(0, 0, 255));
        assert_eq!(hue(1.25), hue(0.25));
        assert_eq!(hue(-0.75), hue(0.25));
    }

    #[test]
    fn text_is_drawn_with_the_embedded_font() {
        let blank = draw_figure(120, 40, |_| Ok(())).unwrap();
        let text = draw_figure(120, 40, |root| {
            root.draw_text("LLH 4.2", &(FONT, 20).into_text_style(root), (5, 5))
                .map_err(figure_error)
        })
        .unwrap();
        let inked = |image: &RgbImage| image.pixels().filter(|p| p.0 != [255; 3]).count();
        assert_eq!(inked(&blank), 0);
        assert!(inked(&text) > 50, "{}", inked(&text));
    }

    /// The lowest row where `a` and `b` differ, or where `a` is inked when `b` is `None`.
    fn lowest_row(a: &RgbImage, b: Option<&RgbImage>) -> u32 {
        a.enumerate_pixels()
            .filter(|(x, y, p)| match b {
                Some(b) => b.get_pixel(*x, *y) != *p,
                None => p.0 != [255; 3],
            })
            .map(|(_, y, _)| y)
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn a_point_sits_on_the_baseline_at_every_size_the_figures_use() {
        // plotters places each glyph at `size / 2 + top` truncated towards zero, which lifts
        // small glyphs by a pixel at odd sizes; the figures use even sizes only.
        for size in [12, 14, 16, 20, 22] {
            let text = |words: &'static str| {
                draw_figure(60, 40, move |root| {
                    let style = (FONT, size).into_text_style(root);
                    root.draw_text(words, &style, (5, 5)).map_err(figure_error)
                })
                .unwrap()
            };
            let (digit, with_point) = (text("0"), text("0."));
            let baseline = lowest_row(&digit, None);
            let point = lowest_row(&with_point, Some(&digit));
            assert!(
                baseline.abs_diff(point) <= 1,
                "size {size}: {baseline} {point}"
            );
        }
    }
}
