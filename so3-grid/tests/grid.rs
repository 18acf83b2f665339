//! Properties of the grids through the public API.
use std::collections::HashSet;
use std::f64::consts::FRAC_PI_2;

use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;
use so3_grid::{
    Grid, GridError, MAX_LEVEL, cell_count, cell_index, cell_parts, cell_volume, geodesic_distance,
    locate, random_rotations, rotation_from_axis_angle,
};

/// The direction `R·ẑ` as (longitude in [0, 2π), latitude).
fn z_axis_lon_lat(q: &UnitQuaternion<f64>) -> (f64, f64) {
    let v = q * Vector3::z();
    (v.y.atan2(v.x).rem_euclid(std::f64::consts::TAU), v.z.asin())
}

/// A rotation whose z-axis points at (lon, lat), turned by `psi` about it.
fn pointing_at(lon: f64, lat: f64, psi: f64) -> UnitQuaternion<f64> {
    let about = |axis: Vector3<f64>, angle| rotation_from_axis_angle(&axis, angle).unwrap();
    about(Vector3::z(), lon) * about(Vector3::y(), FRAC_PI_2 - lat) * about(Vector3::z(), psi)
}

#[test]
fn cardinality_and_unit_norm_at_levels_0_to_5() {
    for level in 0..=5u8 {
        let grid = Grid::new(level).unwrap();
        let rotations = grid.rotations();
        assert_eq!(rotations.len() as u64, 72 * 8u64.pow(level.into()));
        assert_eq!(grid.len(), cell_count(level));
        assert!(
            (grid.cell_volume() * grid.len() as f64 - std::f64::consts::PI.powi(2)).abs() < 1e-9
        );
        for q in &rotations {
            assert!((q.as_ref().norm() - 1.0).abs() < 1e-12);
            assert!(q.as_ref().w >= 0.0);
        }
    }
}

#[test]
fn rotations_are_distinct_and_never_both_q_and_minus_q() {
    for level in 0..=4u8 {
        let rotations = Grid::new(level).unwrap().rotations();
        let mut seen = HashSet::new();
        for q in &rotations {
            // The canonical w ≥ 0 form, rounded: q and −q of one rotation collide here.
            let c = so3_grid::rotation_to_wxyz(q).map(|v| (v * 1e9).round() as i64);
            assert!(
                seen.insert(c),
                "level {level}: rotation {q:?} appears twice"
            );
        }
    }
}

#[test]
fn every_cell_has_8_distinct_children_inside_it_and_they_tile_the_next_level() {
    for level in 0..=3u8 {
        let (grid, fine) = (Grid::new(level).unwrap(), Grid::new(level + 1).unwrap());
        let fine_rotations = fine.rotations();
        let mut covered = vec![0u8; fine.len() as usize];
        for index in 0..grid.len() {
            let kids: Vec<u64> = grid.children(index).unwrap().collect();
            assert_eq!(kids.len(), 8);
            for (a, &kid) in kids.iter().enumerate() {
                covered[kid as usize] += 1;
                let centre = fine_rotations[kid as usize];
                assert_eq!(fine.rotation(kid).unwrap(), centre);
                // A child's centre is inside its parent's cell, and locates to the child.
                assert_eq!(grid.locate(&centre).unwrap(), index);
                assert_eq!(fine.locate(&centre).unwrap(), kid);
                assert_eq!(fine.parent(kid).unwrap(), index);
                for &other in &kids[a + 1..] {
                    let d = geodesic_distance(&centre, &fine_rotations[other as usize]);
                    assert!(d > 1e-6, "children {kid} and {other} coincide");
                }
            }
        }
        assert!(
            covered.iter().all(|&n| n == 1),
            "level {}: children do not tile it",
            level + 1
        );
    }
}

#[test]
fn cells_have_equal_volume() {
    // Uniform random rotations fall into the 576 level-1 cells equally often.
    let level = 1;
    let samples = random_rotations(400_000, 11);
    let mut counts = vec![0u32; cell_count(level) as usize];
    for q in &samples {
        counts[locate(level, q).unwrap() as usize] += 1;
    }
    let expected = samples.len() as f64 / counts.len() as f64; // ≈ 694, σ ≈ 26
    for (cell, &n) in counts.iter().enumerate() {
        let deviation = (f64::from(n) - expected).abs() / expected;
        assert!(
            deviation < 0.2,
            "cell {cell}: {n} samples, expected {expected:.0}"
        );
    }
    assert!(
        (cell_volume(level) * counts.len() as f64 - std::f64::consts::PI.powi(2)).abs() < 1e-12
    );
}

#[test]
fn pixel_centres_and_hashes_match_published_healpy_values() {
    let fixture = include_str!("data/healpy_nested.txt");
    let (mut centres, mut hashes) = (0, 0);
    for line in fixture.lines().filter(|l| !l.starts_with('#')) {
        let f: Vec<&str> = line.split_whitespace().collect();
        let depth: u8 = f[1].parse().unwrap();
        match f[0] {
            "center" => {
                let pixel: u64 = f[2].parse().unwrap();
                let (lon, lat): (f64, f64) = (f[3].parse().unwrap(), f[4].parse().unwrap());
                let grid = Grid::new(depth).unwrap();
                let centre = grid.rotation(cell_index(depth, pixel, 0).unwrap()).unwrap();
                let (our_lon, our_lat) = z_axis_lon_lat(&centre);
                assert!((our_lat - lat).abs() < 1e-9, "depth {depth} pixel {pixel}");
                let lon_gap = (our_lon - lon).rem_euclid(std::f64::consts::TAU);
                assert!(lon_gap.min(std::f64::consts::TAU - lon_gap) < 1e-9);
                centres += 1;
            }
            "hash" => {
                let (lon, lat): (f64, f64) = (f[2].parse().unwrap(), f[3].parse().unwrap());
                let pixel: u64 = f[4].parse().unwrap();
                let cell = locate(depth, &pointing_at(lon, lat, 1.0)).unwrap();
                assert_eq!(
                    cell_parts(depth, cell).unwrap().0,
                    pixel,
                    "lon {lon} lat {lat}"
                );
                hashes += 1;
            }
            other => panic!("unknown fixture record {other}"),
        }
    }
    assert_eq!((centres, hashes), (12 + 48 + 192 + 768, 300));
}

#[test]
fn covering_radius_halves_per_level() {
    let queries = random_rotations(20_000, 5);
    let radius: Vec<f64> = (1..=4u8)
        .map(|level| {
            let grid = Grid::new(level).unwrap();
            queries
                .iter()
                .map(|q| grid.nearest(q).unwrap().1)
                .fold(0.0, f64::max)
        })
        .collect();
    for pair in radius.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!((1.6..2.5).contains(&ratio), "covering radii {radius:?}");
    }
}

#[test]
fn cells_are_compact_and_shrink_by_half_per_level() {
    // The farthest a rotation gets from the centre of the cell containing it (Euler-angle
    // parametrisations fail this near the poles, where cells span 90° of rotation).
    let queries = random_rotations(50_000, 8);
    let worst: Vec<f64> = (1..=4u8)
        .map(|level| {
            let grid = Grid::new(level).unwrap();
            let rotations = grid.rotations();
            queries
                .iter()
                .map(|q| geodesic_distance(q, &rotations[grid.locate(q).unwrap() as usize]))
                .fold(0.0, f64::max)
                .to_degrees()
        })
        .collect();
    assert!(worst[0] < 55.0, "{worst:?}");
    for pair in worst.windows(2) {
        assert!((1.7..2.3).contains(&(pair[0] / pair[1])), "{worst:?}");
    }
}

#[test]
fn bad_levels_and_rotations_are_errors() {
    assert!(matches!(
        Grid::new(MAX_LEVEL + 1),
        Err(GridError::LevelOutOfRange { .. })
    ));
    let grid = Grid::new(1).unwrap();
    assert!(matches!(
        grid.rotation(576),
        Err(GridError::CellOutOfRange { .. })
    ));
    let nan = UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(f64::NAN, 0.0, 0.0, 0.0));
    assert!(matches!(
        grid.locate(&nan),
        Err(GridError::NonFinite { .. })
    ));
    assert!(matches!(
        grid.nearest(&nan),
        Err(GridError::NonFinite { .. })
    ));
    assert!(matches!(
        cell_index(1, 48, 0),
        Err(GridError::PartOutOfRange { .. })
    ));
    assert!(matches!(
        cell_parts(0, 72),
        Err(GridError::CellOutOfRange { .. })
    ));
}

#[test]
fn random_rotations_are_reproducible_at_any_thread_count() {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let a = one.install(|| random_rotations(10_000, 42));
    let b = random_rotations(10_000, 42);
    assert_eq!(a, b);
    assert_ne!(a, random_rotations(10_000, 43));
    // Uniform: the mean angle to the identity is π/2 + 2/π (≈ 126.5°).
    let mean = b.iter().map(|q| q.angle()).sum::<f64>() / b.len() as f64;
    assert!(
        (mean - (FRAC_PI_2 + 2.0 / std::f64::consts::PI)).abs() < 0.01,
        "{mean}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn nearest_agrees_with_brute_force(level in 0u8..=3, seed in any::<u64>()) {
        let grid = Grid::new(level).unwrap();
        let rotations = grid.rotations();
        for q in random_rotations(8, seed) {
            let (cell, distance) = grid.nearest(&q).unwrap();
            let brute = rotations.iter().map(|r| geodesic_distance(r, &q)).fold(f64::INFINITY, f64::min);
            prop_assert!((distance - brute).abs() < 1e-7, "nearest {distance} brute {brute}");
            prop_assert!((geodesic_distance(&rotations[cell as usize], &q) - brute).abs() < 1e-7);
        }
    }

    #[test]
    fn locate_is_consistent_across_levels(level in 0u8..6, seed in any::<u64>()) {
        let q = random_rotations(1, seed)[0];
        let coarse = locate(level, &q).unwrap();
        let fine = locate(level + 1, &q).unwrap();
        prop_assert!(so3_grid::children(level, coarse).unwrap().contains(&fine));
    }
}
