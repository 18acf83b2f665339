//! A distribution over translations against the ground truth: the cells of the hierarchical
//! distribution, as offsets from the ground-truth translation (mm, camera frame), seen from
//! above (x across, z the depth) and as the camera sees them (x across, y down); marker area is
//! the cell's probability, the cross the ground truth, the red ring the most likely translation.
use image::RgbImage;
use nalgebra::Vector3;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::style::{FONT, draw_figure, figure_error};
use crate::Error;

/// The figure frames the cells holding this much of the probability.
const FRAMED_MASS: f64 = 0.95;
/// The smallest half-width of the frame (mm).
const MIN_HALF_WIDTH_MM: f64 = 10.0;
/// The largest marker's radius (pixels).
const MAX_MARKER: f64 = 12.0;

/// The figure of a translation distribution: cells at `centres` (mm) with `masses`, the
/// ground truth `truth` and the most likely translation `argmax` (mm), under `title`.
pub fn plot_translation(
    centres: &[Vector3<f64>],
    masses: &[f64],
    truth: &Vector3<f64>,
    argmax: &Vector3<f64>,
    title: &str,
) -> Result<RgbImage, Error> {
    let offsets: Vec<(Vector3<f64>, f64)> = centres
        .iter()
        .zip(masses)
        .map(|(c, &m)| (c - truth, m))
        .collect();
    let half = half_width(&offsets, &(argmax - truth));
    let heaviest = masses.iter().copied().fold(f64::MIN_POSITIVE, f64::max);
    draw_figure(1000, 520, |root| {
        let (caption, body) = root.split_vertically(40);
        caption
            .draw_text(title, &(FONT, 20).into_text_style(root), (12, 10))
            .map_err(figure_error)?;
        let panels = body.split_evenly((1, 2));
        let views: [(&str, &str, usize); 2] = [
            ("from above", "z (depth) − ground truth (mm)", 2),
            ("as the camera sees it", "y (down) − ground truth (mm)", 1),
        ];
        for (area, (view, axis, k)) in panels.iter().zip(views) {
            panel(
                area,
                view,
                axis,
                k,
                half,
                &offsets,
                heaviest,
                &(argmax - truth),
            )?;
        }
        Ok(())
    })
}

/// Half the side of the square frame: it holds the cells of [`FRAMED_MASS`] and the most
/// likely translation.
fn half_width(offsets: &[(Vector3<f64>, f64)], argmax: &Vector3<f64>) -> f64 {
    let mut by_mass: Vec<&(Vector3<f64>, f64)> = offsets.iter().collect();
    by_mass.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut held = 0.0;
    let mut half = argmax.amax();
    for (offset, mass) in by_mass {
        if held >= FRAMED_MASS {
            break;
        }
        held += mass;
        half = half.max(offset.amax());
    }
    (1.2 * half).max(MIN_HALF_WIDTH_MM)
}

/// One view: x across, coordinate `k` up the panel.
#[allow(clippy::too_many_arguments)]
fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    view: &str,
    axis: &str,
    k: usize,
    half: f64,
    offsets: &[(Vector3<f64>, f64)],
    heaviest: f64,
    argmax: &Vector3<f64>,
) -> Result<(), Error> {
    let mut chart = ChartBuilder::on(area)
        .caption(view, (FONT, 16))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(56)
        .build_cartesian_2d(-half..half, -half..half)
        .map_err(figure_error)?;
    chart
        .configure_mesh()
        .x_desc("x − ground truth (mm)")
        .y_desc(axis)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.0}"))
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(figure_error)?;
    let inside = |v: &Vector3<f64>| v.x.abs() <= half && v[k].abs() <= half;
    let colour = RGBColor(31, 119, 180);
    chart
        .draw_series(
            offsets
                .iter()
                .filter(|(v, m)| inside(v) && *m > 1e-4 * heaviest)
                .map(|(v, m)| {
                    let radius = (MAX_MARKER * (m / heaviest).sqrt()).max(1.0);
                    Circle::new((v.x, v[k]), radius as i32, colour.mix(0.45).filled())
                }),
        )
        .map_err(figure_error)?;
    chart
        .draw_series([Cross::new((0.0, 0.0), 8, BLACK.stroke_width(2))])
        .map_err(figure_error)?;
    if inside(argmax) {
        chart
            .draw_series([Circle::new((argmax.x, argmax[k]), 7, RED.stroke_width(2))])
            .map_err(figure_error)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_holds_the_mass_and_the_truth_is_marked() {
        let centres = [
            Vector3::new(0.0, 0.0, 700.0),
            Vector3::new(4.0, 0.0, 706.0),
            Vector3::new(400.0, 0.0, 900.0),
        ];
        let masses = [0.6, 0.399, 0.001];
        let truth = Vector3::new(1.0, 0.0, 702.0);
        let image = plot_translation(&centres, &masses, &truth, &centres[0], "test").unwrap();
        assert_eq!(image.dimensions(), (1000, 520));
        let offsets: Vec<_> = centres
            .iter()
            .zip(masses)
            .map(|(c, m)| (c - truth, m))
            .collect();
        let half = half_width(&offsets, &(centres[0] - truth));
        assert_eq!(half, MIN_HALF_WIDTH_MM, "the far, light cell is left out");
        // The ground truth's cross: in each panel, a point whose two diagonals are black for
        // 5 pixels each way (the axes, the ticks and the text draw no such pattern), near the
        // middle of the panel, where the frame centred on the truth puts it.
        let black = |x: u32, y: u32| image.get_pixel(x, y).0 == [0, 0, 0];
        let is_cross = |x: u32, y: u32| {
            (1..=5).all(|d| {
                black(x - d, y - d)
                    && black(x + d, y + d)
                    && black(x - d, y + d)
                    && black(x + d, y - d)
            })
        };
        for (panel, columns) in [(0, 100..400), (1, 600..900)] {
            let crosses: Vec<(u32, u32)> = columns
                .flat_map(|x| (150..450).map(move |y| (x, y)))
                .filter(|&(x, y)| is_cross(x, y))
                .collect();
            assert!(!crosses.is_empty(), "panel {panel}: no cross");
        }
        let count = |c: [u8; 3]| image.pixels().filter(|p| p.0 == c).count();
        assert!(
            count([255, 0, 0]) > 20,
            "the most likely translation's ring"
        );
    }
}
