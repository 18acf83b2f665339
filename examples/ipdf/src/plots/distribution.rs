//! The Implicit-PDF visualisation of a distribution over SO(3) (Murphy et al. 2021, Fig. 2):
//! the direction of each rotation's first axis on a Mollweide projection of the sphere, the
//! rotation about that axis as hue on a colour wheel, marker area by probability; ground-truth
//! rotations as open circles, or as a line where a continuous symmetry makes them a curve;
//! the input crop beside it.
use image::RgbImage;
use nalgebra::{UnitQuaternion, Vector3};

use super::canvas::{Canvas, hue, text_width};

const WIDTH: u32 = 1000;
const HEIGHT: u32 = 430;
/// Centre and half-axes of the Mollweide ellipse (pixels).
const MAP: (f64, f64, f64, f64) = (655.0, 215.0, 320.0, 160.0);
const BLACK: [u8; 3] = [0, 0, 0];
const GREY: [u8; 3] = [200, 200, 200];

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
/// `title` above.
pub fn plot_distribution(
    crop: &[u8],
    size: usize,
    rotations: &[UnitQuaternion<f64>],
    probabilities: &[f64],
    truth: &[UnitQuaternion<f64>],
    title: &str,
) -> RgbImage {
    let mut canvas = Canvas::new(WIDTH, HEIGHT, [255, 255, 255]);
    canvas.text(20, 12, title, 2, BLACK);
    // The crop, scaled to about 300 pixels.
    let plane = size * size;
    if size > 0 && crop.len() == 3 * plane {
        let pixels: Vec<[u8; 3]> = (0..plane)
            .map(|i| [crop[i], crop[plane + i], crop[2 * plane + i]])
            .collect();
        let scale = (300 / size).max(1) as i64;
        canvas.paste(20, 60, &pixels, size, scale);
    }
    // Meridians every 60° and parallels every 30°.
    for degrees in (-180..=180).step_by(60) {
        let longitude = f64::from(degrees).to_radians();
        let points: Vec<_> = (-90..=90)
            .map(|l| project(longitude, f64::from(l).to_radians()))
            .collect();
        for pair in points.windows(2) {
            canvas.line(pair[0], pair[1], 1.0, GREY);
        }
    }
    for degrees in (-60..=60).step_by(30) {
        let latitude = f64::from(degrees).to_radians();
        canvas.line(
            project(-std::f64::consts::PI, latitude),
            project(std::f64::consts::PI, latitude),
            1.0,
            GREY,
        );
    }
    // The distribution: cells more probable than under a uniform density (and than a
    // thousandth of the peak), lighter ones first so heavy ones stay visible.
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
        canvas.disc(x, y, radius, hue(0.5 + tilt / std::f64::consts::TAU));
    }
    // Ground truth: a line through consecutive members of a continuous set, circles otherwise.
    let continuous = truth.len() > 100;
    let projected: Vec<_> = truth
        .iter()
        .map(|r| {
            let (longitude, latitude, tilt) = coordinates(r);
            (project(longitude, latitude), tilt)
        })
        .collect();
    for (k, &((x, y), tilt)) in projected.iter().enumerate() {
        if continuous {
            if let Some(&((nx, ny), _)) = projected.get(k + 1)
                && (nx - x).hypot(ny - y) < 0.2 * MAP.2
            {
                canvas.line((x, y), (nx, ny), 3.0, BLACK);
            }
        } else {
            canvas.ring(x, y, 11.0, 2.5, BLACK);
            canvas.ring(x, y, 8.5, 2.0, hue(0.5 + tilt / std::f64::consts::TAU));
        }
    }
    // The colour wheel of the rotation about the axis.
    let (wx, wy) = (950.0, 375.0);
    for k in 0..360 {
        let angle = f64::from(k).to_radians();
        for r in 14..26 {
            let r = f64::from(r);
            canvas.point(
                (wx + r * angle.cos()).round() as i64,
                (wy - r * angle.sin()).round() as i64,
                hue(0.5 + angle / std::f64::consts::TAU),
            );
        }
    }
    let label = "TILT";
    canvas.text(
        wx as i64 - text_width(label, 1) / 2,
        wy as i64 - 4,
        label,
        1,
        BLACK,
    );
    canvas.into_image()
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
        let image = plot_distribution(&crop, 8, &rotations, &probabilities, &rotations[7..8], "T");
        let (longitude, latitude, _) = coordinates(&rotations[7]);
        let (x, y) = project(longitude, latitude);
        // The heavy cell's disc is coloured, the truth's ring around it is black.
        assert_ne!(image.get_pixel(x as u32, y as u32).0, [255, 255, 255]);
        assert_eq!(image.get_pixel((x + 11.0) as u32, y as u32).0, [0, 0, 0]);
        // Only the heavy cell is drawn: the map holds no other colour than its and the rings'.
        let disc = image.get_pixel(x as u32, y as u32).0;
        let (cx, cy, rx, ry) = MAP;
        let colours: std::collections::BTreeSet<[u8; 3]> = image
            .enumerate_pixels()
            .filter(|(px, py, _)| {
                let (dx, dy) = ((f64::from(*px) - cx) / rx, (f64::from(*py) - cy) / ry);
                dx * dx + dy * dy < 1.0 && ((f64::from(*px) - x).hypot(f64::from(*py) - y) > 14.0)
            })
            .map(|(_, _, p)| p.0)
            .collect();
        assert!(
            !colours.contains(&disc) && colours.len() <= 2,
            "{colours:?}"
        );
        // The crop is pasted at the left.
        assert_eq!(image.get_pixel(25, 65).0, [128, 128, 128]);
    }
}
