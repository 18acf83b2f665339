//! The Implicit-PDF visualisation of a distribution over SO(3) (Murphy et al. 2021, Fig. 2):
//! the direction of each rotation's first axis on a Mollweide projection of the sphere, the
//! rotation about that axis as hue on a colour wheel, marker area by probability; ground-truth
//! rotations as open circles, or as a line where a continuous symmetry makes them a curve;
//! the input crop beside it.
use image::RgbImage;
use nalgebra::{UnitQuaternion, Vector3};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::style::{FONT, draw_figure, figure_error, hue};
use crate::Error;

const WIDTH: u32 = 1180;
const HEIGHT: u32 = 480;
/// Centre and half-axes of the Mollweide ellipse (pixels).
const MAP: (f64, f64, f64, f64) = (700.0, 235.0, 340.0, 170.0);
const GREY: RGBColor = RGBColor(205, 205, 205);
/// Where the crop is drawn (pixels) and its side.
const CROP: (i32, i32, i32) = (30, 80, 300);

/// The area every figure element is drawn on.
type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Longitude, latitude (radians) of the rotation's first axis, and the rotation about it
/// (the first of its x-y-z Euler angles), as in the reference implementation.
fn coordinates(rotation: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    let m = rotation.to_rotation_matrix();
    let axis: Vector3<f64> = m.matrix().column(0).into();
    let longitude = axis.x.atan2(-axis.y);
    let latitude = axis.z.clamp(-1.0, 1.0).asin();
    let tilt = m[(2, 1)].atan2(m[(2, 2)]);
    (longitude, latitude, tilt)
}

/// Pixel position of `(longitude, latitude)` on the Mollweide map.
fn project(longitude: f64, latitude: f64) -> (f64, f64) {
    // Newton's method on 2θ + sin 2θ = π sin φ.
    let mut theta = latitude;
    for _ in 0..20 {
        let f = 2.0 * theta + (2.0 * theta).sin() - std::f64::consts::PI * latitude.sin();
        let derivative = 2.0 + 2.0 * (2.0 * theta).cos();
        if derivative.abs() < 1e-12 {
            break;
        }
        theta -= f / derivative;
    }
    let x = longitude / std::f64::consts::PI * theta.cos();
    let y = theta.sin();
    (MAP.0 + x * MAP.2, MAP.1 - y * MAP.3)
}

/// The figure: `crop` (8-bit `[3, S, S]`, channel-major, `size` = S) on the left, the
/// distribution (`probabilities[i]` at `rotations[i]`) on the map, `truth` drawn over it,
/// `title` above; a colour wheel of the rotation about the axis and a legend below.
pub fn plot_distribution(
    crop: &[u8],
    size: usize,
    rotations: &[UnitQuaternion<f64>],
    probabilities: &[f64],
    truth: &[UnitQuaternion<f64>],
    title: &str,
) -> Result<RgbImage, Error> {
    draw_figure(WIDTH, HEIGHT, |root| {
        let text = |size: u32| (FONT, size).into_text_style(root);
        root.draw_text(
            title,
            &(FONT, 22).into_font().style(FontStyle::Bold).color(&BLACK),
            (20, 14),
        )
        .map_err(figure_error)?;
        draw_crop(root, crop, size)?;
        draw_graticule(root)?;
        draw_cells(root, rotations, probabilities)?;
        draw_truth(root, truth)?;
        draw_wheel(root)?;
        let legend = "marker area: probability · position: direction of the object's x-axis · \
                      colour: rotation about it · black: the ground-truth set";
        root.draw_text(legend, &text(14), (370, HEIGHT as i32 - 28))
            .map_err(figure_error)
    })
}

/// The crop, scaled to [`CROP`]'s side, with its size beneath.
fn draw_crop(root: &Area<'_>, crop: &[u8], size: usize) -> Result<(), Error> {
    let plane = size * size;
    if size == 0 || crop.len() != 3 * plane {
        return Ok(());
    }
    let (left, top, side) = CROP;
    let step = f64::from(side) / size as f64;
    let corner = |k: usize| (f64::from(left) + k as f64 * step).round() as i32;
    let corner_y = |k: usize| (f64::from(top) + k as f64 * step).round() as i32;
    for v in 0..size {
        for u in 0..size {
            let i = v * size + u;
            let colour = RGBColor(crop[i], crop[plane + i], crop[2 * plane + i]);
            root.draw(&Rectangle::new(
                [(corner(u), corner_y(v)), (corner(u + 1), corner_y(v + 1))],
                colour.filled(),
            ))
            .map_err(figure_error)?;
        }
    }
    root.draw(&Rectangle::new(
        [(left, top), (left + side, top + side)],
        BLACK.stroke_width(1),
    ))
    .map_err(figure_error)?;
    let caption = format!("input crop ({size} × {size} px)");
    root.draw_text(
        &caption,
        &(FONT, 16).into_text_style(root),
        (left, top + side + 10),
    )
    .map_err(figure_error)
}

/// Meridians every 60° and parallels every 30°, with their degrees.
fn draw_graticule(root: &Area<'_>) -> Result<(), Error> {
    let pixel = |(x, y): (f64, f64)| (x.round() as i32, y.round() as i32);
    let label = (FONT, 14).into_text_style(root);
    for degrees in (-180i32..=180).step_by(60) {
        let longitude = f64::from(degrees).to_radians();
        let points: Vec<_> = (-90..=90)
            .map(|l| pixel(project(longitude, f64::from(l).to_radians())))
            .collect();
        root.draw(&PathElement::new(points, GREY.stroke_width(1)))
            .map_err(figure_error)?;
        if degrees.abs() < 180 {
            let (x, y) = pixel(project(longitude, 0.0));
            root.draw_text(&format!("{degrees}°"), &label, (x + 3, y + 3))
                .map_err(figure_error)?;
        }
    }
    for degrees in (-60..=60).step_by(30) {
        let latitude = f64::from(degrees).to_radians();
        let ends = [
            pixel(project(-std::f64::consts::PI, latitude)),
            pixel(project(std::f64::consts::PI, latitude)),
        ];
        root.draw(&PathElement::new(ends.to_vec(), GREY.stroke_width(1)))
            .map_err(figure_error)?;
        if degrees != 0 {
            root.draw_text(
                &format!("{degrees}°"),
                &label,
                (ends[0].0 - 36, ends[0].1 - 7),
            )
            .map_err(figure_error)?;
        }
    }
    Ok(())
}

/// The distribution: cells more probable than under a uniform density (and than a thousandth
/// of the peak), lighter ones first so heavy ones stay visible.
fn draw_cells(
    root: &Area<'_>,
    rotations: &[UnitQuaternion<f64>],
    probabilities: &[f64],
) -> Result<(), Error> {
    let peak = probabilities.iter().copied().fold(0.0, f64::max);
    let cells = probabilities.len().min(rotations.len());
    let floor = (1e-3 * peak).max(1.0 / cells.max(1) as f64);
    let mut order: Vec<usize> = (0..cells)
        .filter(|&i| peak > 0.0 && probabilities[i] > floor)
        .collect();
    order.sort_by(|&a, &b| probabilities[a].total_cmp(&probabilities[b]));
    for &i in order.iter().rev().take(20_000).rev() {
        let (longitude, latitude, tilt) = coordinates(&rotations[i]);
        let (x, y) = project(longitude, latitude);
        let radius = 1.0 + 7.0 * (probabilities[i] / peak).sqrt();
        let colour = hue(0.5 + tilt / std::f64::consts::TAU);
        root.draw(&Circle::new(
            (x.round() as i32, y.round() as i32),
            radius.round() as i32,
            colour.filled(),
        ))
        .map_err(figure_error)?;
    }
    Ok(())
}

/// Ground truth: a line through consecutive members of a continuous set, rings otherwise (black
/// outside, the rotation's colour inside).
fn draw_truth(root: &Area<'_>, truth: &[UnitQuaternion<f64>]) -> Result<(), Error> {
    let continuous = truth.len() > 100;
    let projected: Vec<_> = truth
        .iter()
        .map(|r| {
            let (longitude, latitude, tilt) = coordinates(r);
            let (x, y) = project(longitude, latitude);
            ((x.round() as i32, y.round() as i32), tilt)
        })
        .collect();
    for (k, &((x, y), tilt)) in projected.iter().enumerate() {
        if continuous {
            if let Some(&((nx, ny), _)) = projected.get(k + 1)
                && f64::from(nx - x).hypot(f64::from(ny - y)) < 0.2 * MAP.2
            {
                root.draw(&PathElement::new(
                    vec![(x, y), (nx, ny)],
                    BLACK.stroke_width(3),
                ))
                .map_err(figure_error)?;
            }
        } else {
            let colour = hue(0.5 + tilt / std::f64::consts::TAU);
            root.draw(&Circle::new((x, y), 11, BLACK.stroke_width(3)))
                .map_err(figure_error)?;
            root.draw(&Circle::new((x, y), 8, colour.stroke_width(2)))
                .map_err(figure_error)?;
        }
    }
    Ok(())
}

/// The colour wheel of the rotation about the axis, with its angles.
fn draw_wheel(root: &Area<'_>) -> Result<(), Error> {
    let (cx, cy, inner, outer) = (1110.0, 385.0, 20.0, 36.0);
    for k in 0..120 {
        let (a, b) = (
            f64::from(k) * std::f64::consts::TAU / 120.0,
            f64::from(k + 1) * std::f64::consts::TAU / 120.0,
        );
        let at = |angle: f64, r: f64| {
            (
                (cx + r * angle.cos()).round() as i32,
                (cy - r * angle.sin()).round() as i32,
            )
        };
        let wedge = vec![at(a, inner), at(a, outer), at(b, outer), at(b, inner)];
        let colour = hue(0.5 + 0.5 * (a + b) / std::f64::consts::TAU);
        root.draw(&Polygon::new(wedge, colour.filled()))
            .map_err(figure_error)?;
    }
    let small = (FONT, 12).into_text_style(root);
    for (label, (dx, dy)) in [
        ("0°", (40, -6)),
        ("90°", (-10, -52)),
        ("±180°", (-82, -6)),
        ("−90°", (-14, 40)),
    ] {
        root.draw_text(label, &small, (cx as i32 + dx, cy as i32 + dy))
            .map_err(figure_error)?;
    }
    root.draw_text("tilt", &small, (cx as i32 - 9, cy as i32 - 7))
        .map_err(figure_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_projection_fills_the_ellipse() {
        let (x, y) = project(0.0, 0.0);
        assert!((x - MAP.0).abs() < 1e-9 && (y - MAP.1).abs() < 1e-9);
        let (x, _) = project(std::f64::consts::PI, 0.0);
        assert!((x - (MAP.0 + MAP.2)).abs() < 1e-9);
        let (_, y) = project(0.0, std::f64::consts::FRAC_PI_2);
        assert!((y - (MAP.1 - MAP.3)).abs() < 1e-6);
    }

    #[test]
    fn heavy_cells_and_the_truth_are_drawn() {
        let rotations = so3_grid::random_rotations(50, 3);
        let mut probabilities = vec![0.0; 50];
        probabilities[7] = 1.0;
        let crop = vec![128u8; 3 * 8 * 8];
        let image =
            plot_distribution(&crop, 8, &rotations, &probabilities, &rotations[7..8], "T").unwrap();
        let (longitude, latitude, _) = coordinates(&rotations[7]);
        let (x, y) = project(longitude, latitude);
        // The heavy cell's disc is coloured, the truth's ring around it is black.
        assert_ne!(image.get_pixel(x as u32, y as u32).0, [255, 255, 255]);
        assert_eq!(image.get_pixel((x + 11.0) as u32, y as u32).0, [0, 0, 0]);
        // Only the heavy cell is drawn: away from it the map holds greys alone (the graticule
        // and its degrees), no colour of a cell.
        let disc = image.get_pixel(x as u32, y as u32).0;
        let (cx, cy, rx, ry) = MAP;
        let colours: std::collections::BTreeSet<[u8; 3]> = image
            .enumerate_pixels()
            .filter(|(px, py, _)| {
                let (dx, dy) = ((f64::from(*px) - cx) / rx, (f64::from(*py) - cy) / ry);
                dx * dx + dy * dy < 1.0 && ((f64::from(*px) - x).hypot(f64::from(*py) - y) > 14.0)
            })
            .map(|(_, _, p)| p.0)
            .filter(|[r, g, b]| r != g || g != b)
            .collect();
        assert!(
            !colours.contains(&disc) && colours.is_empty(),
            "{colours:?}"
        );
        // The crop is drawn at the left.
        let (left, top, side) = CROP;
        let inside = |k: i32| (k + side / 2) as u32;
        assert_eq!(
            image.get_pixel(inside(left), inside(top)).0,
            [128, 128, 128]
        );
    }
}
