//! The errors of pseudo labels against the ground truth: per dataset variant, the cumulative
//! distribution of each object's label errors (angle from a label to the nearest ground-truth
//! symmetric pose) on a logarithmic axis, with the 5° of the coverage criterion marked.
use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;
use pseudo_label::{COVERAGE_ANGLE_DEG, LabelReport};

use super::style::{FONT, draw_figure, figure_error};
use crate::Error;

/// The smallest and largest error shown (degrees); smaller errors are drawn at the left edge.
const RANGE_DEG: (f64, f64) = (1e-3, 180.0);

/// matplotlib's ten colours (tab10), one per object.
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The figure of `reports` (one panel per `(title, report)`), each object's errors as a
/// cumulative distribution.
pub fn plot_label_errors(reports: &[(&str, &LabelReport)]) -> Result<RgbImage, Error> {
    let columns = reports.len().max(1);
    draw_figure(560 * columns as u32, 460, |root| {
        for (area, (title, report)) in root.split_evenly((1, columns)).iter().zip(reports) {
            panel(area, title, report)?;
        }
        Ok(())
    })
}

/// One variant's panel.
fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    report: &LabelReport,
) -> Result<(), Error> {
    let mut chart = ChartBuilder::on(area)
        .caption(format!("Pseudo-label errors: {title}"), (FONT, 20))
        .margin(12)
        .x_label_area_size(46)
        .y_label_area_size(60)
        .build_cartesian_2d((RANGE_DEG.0..RANGE_DEG.1).log_scale(), 0.0..1.02)
        .map_err(figure_error)?;
    chart
        .configure_mesh()
        .x_desc("angle to the nearest ground-truth symmetric pose (°, log scale)")
        .y_desc("fraction of labels within")
        .x_label_formatter(&|x| {
            if *x >= 1.0 {
                format!("{x:.0}")
            } else {
                format!("{x}")
            }
        })
        .y_label_formatter(&|y| format!("{y:.1}"))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(figure_error)?;
    let threshold = [(COVERAGE_ANGLE_DEG, 0.0), (COVERAGE_ANGLE_DEG, 1.02)];
    chart
        .draw_series(DashedLineSeries::new(
            threshold,
            6,
            4,
            BLACK.stroke_width(1),
        ))
        .map_err(figure_error)?
        .label(format!("{COVERAGE_ANGLE_DEG}° (coverage criterion)"))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(1)));
    for ((name, scores), &colour) in report.objects.iter().zip(COLOURS.iter().cycle()) {
        let steps = cumulative_steps(&scores.errors_deg);
        let legend = format!(
            "{name}: MAAD {:.2}°, {} label{}, coverage {:.1}%",
            scores.label_maad_deg,
            scores.labels,
            if scores.labels == 1 { "" } else { "s" },
            100.0 * scores.coverage
        );
        chart
            .draw_series(LineSeries::new(steps, colour.stroke_width(2)))
            .map_err(figure_error)?
            .label(legend)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
        .map_err(figure_error)
}

/// The cumulative distribution of `errors_deg` as the corners of a staircase over
/// [`RANGE_DEG`]: `(x, fraction of errors ≤ x)`, a step up at each error (clamped to the
/// range), from 0 at the left edge to the whole fraction at the right.
fn cumulative_steps(errors_deg: &[f64]) -> Vec<(f64, f64)> {
    let mut errors = errors_deg.to_vec();
    errors.sort_by(f64::total_cmp);
    let n = errors.len().max(1) as f64;
    let mut steps = vec![(RANGE_DEG.0, 0.0)];
    for (k, &error) in errors.iter().enumerate() {
        let x = error.clamp(RANGE_DEG.0, RANGE_DEG.1);
        steps.push((x, k as f64 / n));
        steps.push((x, (k + 1) as f64 / n));
    }
    steps.push((RANGE_DEG.1, errors.len() as f64 / n));
    steps
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use proptest::prelude::*;
    use pseudo_label::ObjectLabelScores;

    use super::*;

    proptest! {
        /// Between its corners the staircase stands at the share of errors at or below `x`,
        /// counted one by one.
        #[test]
        fn the_staircase_is_the_share_of_errors_within_each_angle(
            errors in prop::collection::vec(0.002f64..170.0, 1..40),
            x in 0.002f64..170.0,
        ) {
            let steps = cumulative_steps(&errors);
            prop_assert!(steps.windows(2).all(|w| w[0].0 <= w[1].0 && w[0].1 <= w[1].1));
            prop_assert_eq!(steps.first().copied(), Some((RANGE_DEG.0, 0.0)));
            prop_assert_eq!(steps.last().copied(), Some((RANGE_DEG.1, 1.0)));
            // The staircase's height at x: the last corner at or left of x.
            let height = steps.iter().rev().find(|(corner, _)| *corner <= x).unwrap().1;
            let within = errors.iter().filter(|&&e| e <= x).count() as f64 / errors.len() as f64;
            prop_assert!((height - within).abs() < 1e-12, "{height} against {within}");
        }
    }

    #[test]
    fn each_object_gets_its_colour() {
        let scores = |errors: Vec<f64>| ObjectLabelScores {
            labels: errors.len(),
            label_maad_deg: errors.iter().sum::<f64>() / errors.len() as f64,
            errors_deg: errors,
            ..Default::default()
        };
        let report = LabelReport {
            variant: "uniform".into(),
            objects: BTreeMap::from([
                ("bowl".to_string(), scores(vec![0.01, 0.02, 0.5])),
                ("can".to_string(), scores(vec![0.0, 3.0, 170.0])),
            ]),
            ..LabelReport::default()
        };
        let image = plot_label_errors(&[("uniform", &report), ("texture", &report)]).unwrap();
        assert_eq!(image.dimensions(), (1120, 460));
        let has = |c: RGBColor| image.pixels().any(|p| p.0 == [c.0, c.1, c.2]);
        assert!(has(COLOURS[0]) && has(COLOURS[1]) && !has(COLOURS[2]));
    }
}
