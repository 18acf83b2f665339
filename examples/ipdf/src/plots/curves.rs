//! The training curves of a run: loss and validation LLH per epoch, from `train_log.csv`.
use bop_dataset::FileError;
use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::style::{FONT, draw_figure, figure_error};
use crate::Error;

/// matplotlib's first two colours.
const BLUE: RGBColor = RGBColor(31, 119, 180);
const ORANGE: RGBColor = RGBColor(255, 127, 14);

/// One panel's series: `(epoch, value)`.
type Series = Vec<(f64, f64)>;

/// The loss and validation LLH columns of `train_log.csv` (`path` names the file in errors).
pub fn read_train_log(text: &str, path: &std::path::Path) -> Result<(Series, Series), FileError> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| FileError::new(path, name, "column missing"))
    };
    let (epoch, loss, llh) = (column("epoch")?, column("loss")?, column("validation_llh")?);
    let (mut losses, mut llhs) = (Vec::new(), Vec::new());
    for (row, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').collect();
        let value = |i: usize, name: &str| -> Result<Option<f64>, FileError> {
            match cells.get(i).map(|c| c.trim()) {
                None | Some("") => Ok(None),
                Some(text) => text.parse::<f64>().map(Some).map_err(|_| {
                    FileError::new(
                        path,
                        format!("line {}: {name}", row + 2),
                        format!("{text:?} is not a number"),
                    )
                }),
            }
        };
        let Some(e) = value(epoch, "epoch")? else {
            continue;
        };
        if let Some(v) = value(loss, "loss")? {
            losses.push((e, v));
        }
        if let Some(v) = value(llh, "validation_llh")? {
            llhs.push((e, v));
        }
    }
    if losses.is_empty() {
        return Err(FileError::new(path, "loss", "no epoch logged yet"));
    }
    Ok((losses, llhs))
}

/// The grid the validation LLH of `train_log.csv` is measured on (`FitOptions::validation_level`
/// of `ipdf train`: the dense level-2 grid).
const VALIDATION_GRID: &str = "dense level-2 grid, 4,608 cells";

/// One panel: `series` against epochs, with tick values, axis labels and a legend.
fn panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    y_label: &str,
    legend: &str,
    series: &Series,
    colour: RGBColor,
) -> Result<(), Error> {
    // Epochs are whole numbers: an integer axis gets integer ticks.
    let points: Vec<(i64, f64)> = series.iter().map(|&(e, v)| (e.round() as i64, v)).collect();
    let x_low = points.iter().map(|p| p.0).min().unwrap_or(0);
    let x_high = points.iter().map(|p| p.0).max().unwrap_or(1).max(x_low + 1);
    let (y_low, y_high) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    let margin = 0.08 * (y_high - y_low).max(1e-3);
    let (y_low, y_high) = if points.is_empty() {
        (0.0, 1.0)
    } else {
        (y_low - margin, y_high + margin)
    };
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 20))
        .margin(12)
        .x_label_area_size(46)
        .y_label_area_size(64)
        .build_cartesian_2d(x_low..x_high, y_low..y_high)
        .map_err(figure_error)?;
    chart
        .configure_mesh()
        .x_desc("epoch")
        .y_desc(y_label)
        .x_labels(10)
        .y_labels(8)
        .y_label_formatter(&|y| format!("{y:.2}"))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(figure_error)?;
    if series.is_empty() {
        let style = (FONT, 16).into_text_style(area);
        chart
            .draw_series(std::iter::once(Text::new(
                "no validation split",
                (x_low, 0.5),
                style,
            )))
            .map_err(figure_error)?;
        return Ok(());
    }
    chart
        .draw_series(LineSeries::new(
            points.iter().copied(),
            colour.stroke_width(2),
        ))
        .map_err(figure_error)?
        .label(legend)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2)));
    chart
        .draw_series(
            points
                .iter()
                .map(|&point| Circle::new(point, 3, colour.filled())),
        )
        .map_err(figure_error)?;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(figure_error)
}

/// The figure of a run's `train_log.csv` text: training loss and validation LLH per epoch.
pub fn plot_training_curves(text: &str, path: &std::path::Path) -> Result<RgbImage, Error> {
    let (losses, llhs) = read_train_log(text, path)?;
    draw_figure(1200, 480, |root| {
        let panels = root.split_evenly((1, 2));
        panel(
            &panels[0],
            "Training loss",
            "loss (nats)",
            "training loss",
            &losses,
            BLUE,
        )?;
        panel(
            &panels[1],
            &format!("Validation LLH ({VALIDATION_GRID})"),
            "LLH (nats)",
            "validation LLH",
            &llhs,
            ORANGE,
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_log_is_read_and_drawn() {
        let text = "epoch,step,loss,learning_rate,validation_llh,seconds,images_per_second\n\
                    1,10,5.5,1e-4,-1.0,3,10\n2,20,4.0,1e-4,0.5,3,10\n3,30,3.0,1e-4,,3,10\n";
        let (losses, llhs) = read_train_log(text, Path::new("t.csv")).unwrap();
        assert_eq!(losses, vec![(1.0, 5.5), (2.0, 4.0), (3.0, 3.0)]);
        assert_eq!(llhs, vec![(1.0, -1.0), (2.0, 0.5)]);
        let image = plot_training_curves(text, Path::new("t.csv")).unwrap();
        // Each axis spans its series (plus a margin), so a curve runs corner to corner: the
        // loss (5.5 → 3.0) from the top left of its panel to the bottom right, the LLH
        // (−1.0 → 0.5) from the bottom left of its panel to the top right. The leftmost and
        // rightmost pixels of a colour are its first and last points (the legend's swatch lies
        // left of the legend's text, inside the plot).
        let ends = |c: RGBColor, columns: std::ops::Range<u32>| {
            let pixels: Vec<(u32, u32)> = image
                .enumerate_pixels()
                .filter(|(x, _, p)| columns.contains(x) && p.0 == [c.0, c.1, c.2])
                .map(|(x, y, _)| (x, y))
                .collect();
            let left = pixels
                .iter()
                .map(|p| p.0)
                .min()
                .expect("the curve is drawn");
            let right = pixels.iter().map(|p| p.0).max().unwrap();
            let mean_row = |column: u32| {
                let rows: Vec<u32> = pixels
                    .iter()
                    .filter(|p| p.0 == column)
                    .map(|p| p.1)
                    .collect();
                rows.iter().sum::<u32>() as f64 / rows.len() as f64
            };
            (right - left, mean_row(left), mean_row(right))
        };
        let half = image.width() / 2;
        let (loss_span, loss_first, loss_last) = ends(BLUE, 0..half);
        let (llh_span, llh_first, llh_last) = ends(ORANGE, half..image.width());
        let tall = 0.5 * f64::from(image.height());
        assert!(
            loss_span > half / 2 && llh_span > half / 2,
            "{loss_span} {llh_span}"
        );
        assert!(
            loss_last - loss_first > 0.6 * tall,
            "{loss_first} → {loss_last}"
        );
        assert!(
            llh_first - llh_last > 0.6 * tall,
            "{llh_first} → {llh_last}"
        );
        let bad = "epoch,loss,validation_llh\n1,x,2\n";
        assert_eq!(
            read_train_log(bad, Path::new("t.csv")).unwrap_err().field,
            "line 2: loss"
        );
        assert_eq!(
            read_train_log("a,b\n", Path::new("t.csv"))
                .unwrap_err()
                .field,
            "epoch"
        );
    }
}
