//! The training curves of a run: loss and validation LLH per epoch, from `train_log.csv`.
use image::RgbImage;

use super::canvas::{Canvas, text_width};
use bop_dataset::FileError;

const BLACK: [u8; 3] = [0, 0, 0];
const BLUE: [u8; 3] = [31, 119, 180];
const ORANGE: [u8; 3] = [255, 127, 14];

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

/// Draws one panel at `(left, top)` of `width × height` pixels.
fn panel(
    canvas: &mut Canvas,
    (left, top, width, height): (f64, f64, f64, f64),
    title: &str,
    series: &Series,
    colour: [u8; 3],
) {
    canvas.text(left as i64, top as i64 - 30, title, 2, BLACK);
    let corners = [
        (left, top),
        (left + width, top),
        (left + width, top + height),
        (left, top + height),
        (left, top),
    ];
    for pair in corners.windows(2) {
        canvas.line(pair[0], pair[1], 1.0, BLACK);
    }
    if series.is_empty() {
        canvas.text(
            left as i64 + 10,
            (top + 0.5 * height) as i64,
            "NO VALIDATION DATA",
            2,
            BLACK,
        );
        return;
    }
    let (x_low, x_high) = series
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    let (y_low, y_high) = series
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    let (x_span, y_span) = ((x_high - x_low).max(1e-9), (y_high - y_low).max(1e-9));
    let at = |(x, y): (f64, f64)| {
        (
            left + 10.0 + (x - x_low) / x_span * (width - 20.0),
            top + height - 10.0 - (y - y_low) / y_span * (height - 20.0),
        )
    };
    for pair in series.windows(2) {
        canvas.line(at(pair[0]), at(pair[1]), 2.5, colour);
    }
    for &point in series {
        let (x, y) = at(point);
        canvas.disc(x, y, 3.5, colour);
    }
    let format = |v: f64| format!("{v:.3}");
    canvas.text(
        left as i64 - text_width(&format(y_high), 1) - 6,
        top as i64 + 6,
        &format(y_high),
        1,
        BLACK,
    );
    canvas.text(
        left as i64 - text_width(&format(y_low), 1) - 6,
        (top + height) as i64 - 14,
        &format(y_low),
        1,
        BLACK,
    );
    let (first, last) = (format!("{x_low:.0}"), format!("{x_high:.0}"));
    canvas.text(left as i64 + 6, (top + height) as i64 + 8, &first, 1, BLACK);
    canvas.text(
        (left + width) as i64 - text_width(&last, 1) - 6,
        (top + height) as i64 + 8,
        &last,
        1,
        BLACK,
    );
    canvas.text(
        (left + 0.5 * width) as i64 - text_width("EPOCH", 1) / 2,
        (top + height) as i64 + 8,
        "EPOCH",
        1,
        BLACK,
    );
}

/// The figure of a run's `train_log.csv` text: training loss and validation LLH per epoch.
pub fn plot_training_curves(text: &str, path: &std::path::Path) -> Result<RgbImage, FileError> {
    let (losses, llhs) = read_train_log(text, path)?;
    let mut canvas = Canvas::new(1000, 420, [255, 255, 255]);
    panel(
        &mut canvas,
        (80.0, 60.0, 380.0, 310.0),
        "TRAINING LOSS",
        &losses,
        BLUE,
    );
    panel(
        &mut canvas,
        (580.0, 60.0, 380.0, 310.0),
        "VALIDATION LLH",
        &llhs,
        ORANGE,
    );
    Ok(canvas.into_image())
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
        assert!(image.pixels().any(|p| p.0 == BLUE) && image.pixels().any(|p| p.0 == ORANGE));
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
