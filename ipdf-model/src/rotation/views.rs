//! Test-time views of a crop: the crop and copies of it zoomed and shifted by a few percent of
//! its side, whose image terms [`crate::rotation::Predictor::with_views`] averages. A small
//! network's answer can change with a shift of a pixel or a zoom of a few percent, which say
//! nothing of the rotation; averaging over such views takes its answer away from what one cut
//! happens to show. A rotation changes little under them (the line of sight turns by a
//! fraction of the crop's field of view); a translation would, so only the rotation model
//! uses them.
use tch::{Kind, Tensor};

use crate::ModelError;

/// How far each extra view moves the crop, as a fraction of its half-side: zoomed in or out by
/// this fraction, or shifted by it along x, y or both. Measured on the ten real YCB-Video
/// objects' quick-preset models with 8 extra views (docs/experiments.md, "Views of the crop at
/// test time"): 0.03, 0.045 and 0.06 each raised the validation renders' LLH of every object, and
/// 0.03 alone kept every real instance whose truth had been denser than uniform so.
pub const VIEW_SHIFT: f64 = 0.03;

/// Extra views at most: zoom in, zoom out, shifts along ±x and ±y, and the two diagonals
/// zoomed.
pub const MAX_EXTRA_VIEWS: usize = 8;

/// The first `extra` views' affine maps (`[scale, 0, shift x, 0, scale, shift y]`, from the
/// view's normalised coordinates in `[-1, 1]` to the crop's), after the crop itself.
fn view_maps(extra: usize) -> impl Iterator<Item = [f64; 6]> {
    let d = VIEW_SHIFT;
    let moves = [
        (1.0 + d, 0.0, 0.0),
        (1.0 - d, 0.0, 0.0),
        (1.0, d, 0.0),
        (1.0, -d, 0.0),
        (1.0, 0.0, d),
        (1.0, 0.0, -d),
        (1.0 + d, d, d),
        (1.0 - d, -d, -d),
    ];
    moves
        .into_iter()
        .take(extra)
        .map(|(scale, x, y)| [scale, 0.0, x, 0.0, scale, y])
}

/// Checks that `extra` views can be made.
pub(crate) fn validate_views(extra: usize) -> Result<(), ModelError> {
    if extra > MAX_EXTRA_VIEWS {
        return Err(ModelError::option(
            "views",
            format!("{extra} extra views: at most {MAX_EXTRA_VIEWS}"),
        ));
    }
    Ok(())
}

/// `[1 + extra, 3, S, S]`: the crop `[1, 3, S, S]` and its first `extra` views, each sampled
/// bilinearly from it, zero outside it (the masked background's value).
pub fn crop_views(crop: &Tensor, extra: usize) -> Tensor {
    if extra == 0 {
        return crop.shallow_clone();
    }
    let crop = crop.to_kind(Kind::Float);
    let maps: Vec<f32> = view_maps(extra).flatten().map(|v| v as f32).collect();
    let theta = Tensor::from_slice(&maps)
        .reshape([extra as i64, 2, 3])
        .to_device(crop.device());
    let size = crop.size();
    let grid =
        Tensor::affine_grid_generator(&theta, [extra as i64, size[1], size[2], size[3]], false);
    let views = crop
        .expand([extra as i64, size[1], size[2], size[3]], false)
        .grid_sampler(&grid, 0, 0, false);
    Tensor::cat(&[crop, views], 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bilinear sampling written out: the crop at continuous pixel `(u, v)` (pixel centres at
    /// integers), zero outside.
    fn sample(crop: &[f32], side: usize, u: f64, v: f64) -> f64 {
        let at = |x: i64, y: i64| {
            if x < 0 || y < 0 || x >= side as i64 || y >= side as i64 {
                0.0
            } else {
                f64::from(crop[y as usize * side + x as usize])
            }
        };
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        at(x0, y0) * (1.0 - fx) * (1.0 - fy)
            + at(x0 + 1, y0) * fx * (1.0 - fy)
            + at(x0, y0 + 1) * (1.0 - fx) * fy
            + at(x0 + 1, y0 + 1) * fx * fy
    }

    #[test]
    fn each_view_is_the_crop_zoomed_and_shifted_as_documented() {
        let side = 12usize;
        // One channel repeated: a ramp with a bright square, so that a shift or zoom shows.
        let plane: Vec<f32> = (0..side * side)
            .map(|i| {
                let (x, y) = (i % side, i / side);
                let square = if (3..7).contains(&x) && (4..9).contains(&y) {
                    0.5
                } else {
                    0.0
                };
                x as f32 / 24.0 + square
            })
            .collect();
        let crop = Tensor::from_slice(&plane)
            .reshape([1, 1, side as i64, side as i64])
            .repeat([1, 3, 1, 1]);
        let views = crop_views(&crop, MAX_EXTRA_VIEWS);
        assert_eq!(views.size(), [9, 3, side as i64, side as i64]);
        let values: Vec<f32> = Vec::try_from(views.flatten(0, -1)).unwrap();
        let n = side * side;
        for (k, map) in std::iter::once([1.0, 0.0, 0.0, 0.0, 1.0, 0.0])
            .chain(view_maps(MAX_EXTRA_VIEWS))
            .enumerate()
        {
            for channel in 0..3 {
                let got = &values[(k * 3 + channel) * n..][..n];
                for (i, &value) in got.iter().enumerate() {
                    // The pixel centre in normalised coordinates, mapped into the crop.
                    let to_unit = |p: usize| (2.0 * p as f64 + 1.0) / side as f64 - 1.0;
                    let (x, y) = (to_unit(i % side), to_unit(i / side));
                    let (cx, cy) = (map[0] * x + map[2], map[4] * y + map[5]);
                    let to_pixel = |c: f64| ((c + 1.0) * side as f64 - 1.0) / 2.0;
                    let expected = sample(&plane, side, to_pixel(cx), to_pixel(cy));
                    assert!(
                        (f64::from(value) - expected).abs() < 1e-5,
                        "view {k}, pixel {i}: {value} against {expected}"
                    );
                }
            }
        }
        // The views differ from the crop: every map moves it.
        for k in 1..9 {
            let moved = &values[k * 3 * n..][..n];
            assert!(
                moved.iter().zip(&plane).any(|(a, b)| (a - b).abs() > 1e-3),
                "view {k}"
            );
        }
    }

    #[test]
    fn more_views_than_there_are_are_refused() {
        assert!(validate_views(MAX_EXTRA_VIEWS).is_ok());
        let error = validate_views(MAX_EXTRA_VIEWS + 1).unwrap_err().to_string();
        assert!(error.contains("views"), "{error}");
    }
}
