//! The paper's metric definitions checked on distributions with known answers.
use std::f64::consts::{FRAC_PI_2, PI};

use ipdf_metrics::{
    Distribution, GridCell, MetricsError, RECALL_THRESHOLD, SymmetryGroup, llh, maad, recall_maad,
    recall_min_log_density,
};
use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;
use so3_grid::{Grid, cell_volume, geodesic_distance, random_rotations};

fn one_hot(grid: &Grid, cells: &[u64]) -> Distribution {
    let mut masses = vec![0.0; grid.len() as usize];
    for &cell in cells {
        masses[cell as usize] += 1.0 / cells.len() as f64;
    }
    Distribution::dense(grid, masses).unwrap()
}

/// A can's group (its axis and the flip), a box's (three half-turns) or a cone's (its axis).
fn test_group(kind: u8) -> SymmetryGroup {
    let mut group = SymmetryGroup::none();
    let half_turn = |axis: Vector3<f64>| nalgebra::Isometry3::rotation(axis * PI);
    match kind % 3 {
        0 => {
            group.continuous.push(ipdf_metrics::ContinuousSymmetry {
                axis: Vector3::z_axis(),
                offset: Vector3::zeros(),
            });
            group.discrete.push(half_turn(Vector3::x()));
        }
        1 => {
            group.discrete = vec![
                half_turn(Vector3::x()),
                half_turn(Vector3::y()),
                half_turn(Vector3::z()),
            ];
        }
        _ => group.continuous.push(ipdf_metrics::ContinuousSymmetry {
            axis: Vector3::y_axis(),
            offset: Vector3::zeros(),
        }),
    }
    group
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// The exact distance to a symmetry set agrees with the nearest member of its
    /// discretisation (200 steps per turn: at most 0.9° apart), and never exceeds it.
    #[test]
    fn class_distances_match_the_discretised_set(kind in 0u8..3, seed in any::<u64>()) {
        let group = test_group(kind);
        let rotations = random_rotations(6, seed);
        let truth = rotations[0];
        let set = group.expand(&truth);
        let sampled = ipdf_metrics::nearest_distances(&rotations[1..], &set);
        for (rotation, sampled) in rotations[1..].iter().zip(sampled) {
            let exact = group.class_distances(&truth, rotation).into_iter().fold(f64::INFINITY, f64::min);
            // (nearest_distances is exact to 1e-4 rad away from the set.)
            prop_assert!(exact <= sampled + 1e-4 && sampled - exact < (0.5 * PI / 100.0), "{exact} {sampled}");
        }
        // Every member of the set is at distance 0 from its own class.
        for member in set.iter().step_by(37) {
            let nearest = group.class_distances(&truth, member).into_iter().fold(f64::INFINITY, f64::min);
            prop_assert!(nearest < 1e-6);
        }
        prop_assert_eq!(group.classes().len(), [2, 4, 1][kind as usize]);
    }

    /// A symmetry set holds each rotation once: a discrete symmetry listed twice, or one a
    /// continuous axis already generates, adds nothing; what remains is pairwise distinct.
    #[test]
    fn symmetry_sets_hold_each_rotation_once(kind in 0u8..3, steps in 1usize..60) {
        let mut group = test_group(kind);
        group.discrete.extend(group.discrete.clone());
        if let Some(axis) = group.continuous.first().map(|c| c.axis) {
            // A turn the axis's discretisation also makes (one step), slightly perturbed.
            let step = std::f64::consts::TAU / steps as f64 + 1e-9;
            group.discrete.push(nalgebra::Isometry3::rotation(axis.into_inner() * step));
        }
        let rotations = group.rotations(steps);
        prop_assert_eq!(rotations.len(), [2 * steps, 4, steps][kind as usize]);
        for (i, a) in rotations.iter().enumerate() {
            for b in &rotations[i + 1..] {
                prop_assert!(geodesic_distance(a, b) > 1e-6);
            }
        }
    }

    #[test]
    fn uniform_scores_minus_ln_pi_squared(level in 0u8..=3, seed in any::<u64>()) {
        let uniform = Distribution::uniform(&Grid::new(level).unwrap());
        let gt = random_rotations(5, seed);
        prop_assert!((llh(&uniform, &gt).unwrap() + (PI * PI).ln()).abs() < 1e-9);
    }

    #[test]
    fn mass_on_the_gt_cell_gives_log_inverse_volume_and_small_maad(level in 1u8..=3, seed in any::<u64>()) {
        let grid = Grid::new(level).unwrap();
        let gt = random_rotations(1, seed);
        let dist = one_hot(&grid, &[grid.locate(&gt[0]).unwrap()]);
        prop_assert!((llh(&dist, &gt).unwrap() - (1.0 / cell_volume(level)).ln()).abs() < 1e-9);
        // The containing cell's centre is within about one cell size of the rotation.
        let spacing = 120f64 / f64::from(1u32 << level);
        prop_assert!(maad(&dist, &gt).unwrap() < spacing);
        prop_assert!(recall_maad(&dist, &gt, RECALL_THRESHOLD).unwrap() < spacing);
    }

    #[test]
    fn a_larger_gt_set_never_raises_maad(seed in any::<u64>()) {
        let grid = Grid::new(2).unwrap();
        let masses: Vec<f64> = random_rotations(grid.len() as usize, seed)
            .iter().map(|q| q.angle() + 0.01).collect();
        let sum: f64 = masses.iter().sum();
        let dist = Distribution::dense(&grid, masses.iter().map(|m| m / sum).collect()).unwrap();
        let small = random_rotations(3, seed ^ 1);
        let mut large = small.clone();
        large.extend(random_rotations(4, seed ^ 2));
        prop_assert!(maad(&dist, &large).unwrap() <= maad(&dist, &small).unwrap() + 1e-12);
    }

    #[test]
    fn maad_is_the_mass_weighted_distance(seed in any::<u64>()) {
        let grid = Grid::new(1).unwrap();
        let masses: Vec<f64> = (0..grid.len()).map(|i| ((i * 7919 + seed % 97) % 13) as f64).collect();
        let sum: f64 = masses.iter().sum();
        let dist = Distribution::dense(&grid, masses.iter().map(|m| m / sum).collect()).unwrap();
        let gt = random_rotations(3, seed);
        let brute: f64 = dist.rotations().iter().zip(dist.masses()).map(|(r, m)| {
            m * gt.iter().map(|g| geodesic_distance(r, g)).fold(f64::INFINITY, f64::min)
        }).sum();
        // The f32 search is within 0.01° (exact in f64 below 1.7°).
        prop_assert!((maad(&dist, &gt).unwrap() - brute.to_degrees()).abs() < 1e-2);
    }
}

#[test]
fn uniform_maad_is_the_mean_angle_of_a_random_rotation() {
    let uniform = Distribution::uniform(&Grid::new(4).unwrap());
    let expected = (FRAC_PI_2 + 2.0 / PI).to_degrees(); // 126.476°
    for gt in random_rotations(3, 9) {
        let value = maad(&uniform, &[gt]).unwrap();
        assert!((value - expected).abs() < 0.05, "{value} vs {expected}");
    }
}

#[test]
fn symmetric_gt_sets_lower_maad_and_recall_needs_every_member() {
    let grid = Grid::new(3).unwrap();
    let pose = random_rotations(1, 3)[0];
    let flip = SymmetryGroup::cyclic(&Vector3::x(), 2).unwrap();
    let set = flip.expand(&pose);
    assert_eq!(set.len(), 2);
    // All mass on the cell of the first member only.
    let half = one_hot(&grid, &[grid.locate(&set[0]).unwrap()]);
    // MAAD against the set is small (mass sits on a member) ...
    assert!(maad(&half, &set).unwrap() < 8.0);
    // ... but recall is poor: the other member is 180° away from anything predicted.
    let recall = recall_maad(&half, &set, RECALL_THRESHOLD).unwrap();
    assert!((recall - 90.0).abs() < 8.0, "{recall}");
    // Mass on both members recalls both.
    let both = one_hot(
        &grid,
        &set.iter()
            .map(|q| grid.locate(q).unwrap())
            .collect::<Vec<_>>(),
    );
    assert!(recall_maad(&both, &set, RECALL_THRESHOLD).unwrap() < 8.0);
    // The uniform distribution scores lower MAAD against the 2-element set than against one.
    let uniform = Distribution::uniform(&grid);
    assert!(maad(&uniform, &set).unwrap() < maad(&uniform, &set[..1]).unwrap() - 10.0);
}

#[test]
fn recall_admits_cells_exactly_above_the_minimum_log_density() {
    // One cell of a level-3 grid at a chosen density, the rest of the mass on a cell far from
    // it: the first joins the predicted set (recall of its own rotation ≈ 0) just above the
    // minimum log density and not just below it (then only the other cell is predicted).
    let grid = Grid::new(3).unwrap();
    let minimum = recall_min_log_density(RECALL_THRESHOLD);
    assert!((minimum - (RECALL_THRESHOLD * 294_912.0 / PI.powi(2)).ln()).abs() < 1e-9);
    let rotations = random_rotations(2, 8);
    let (target, elsewhere) = (
        grid.locate(&rotations[0]).unwrap(),
        grid.locate(&rotations[1]).unwrap(),
    );
    assert_ne!(target, elsewhere);
    let recall_at = |factor: f64| {
        let mass = (minimum.exp() * factor) * cell_volume(3);
        let mut masses = vec![0.0; grid.len() as usize];
        masses[target as usize] = mass;
        masses[elsewhere as usize] = 1.0 - mass;
        let dist = Distribution::dense(&grid, masses).unwrap();
        recall_maad(&dist, &[rotations[0]], RECALL_THRESHOLD).unwrap()
    };
    assert!(recall_at(1.01) < 8.0);
    assert!(recall_at(0.99) > 8.0);
}

#[test]
fn mixed_levels_score_like_the_dense_grid_they_refine() {
    // A level-2 distribution, then the same mass with one cell refined into its 8 children at
    // level 3 (mass split evenly keeps the density): LLH and recall agree, MAAD nearly so.
    let coarse = Grid::new(2).unwrap();
    let gt = random_rotations(1, 21)[0];
    let peak = coarse.locate(&gt).unwrap();
    let mut masses = vec![0.5 / (coarse.len() - 1) as f64; coarse.len() as usize];
    masses[peak as usize] = 0.5;
    let dense = Distribution::dense(&coarse, masses.clone()).unwrap();

    let mut cells = Vec::new();
    let mut mixed_masses = Vec::new();
    for index in 0..coarse.len() {
        if index == peak {
            for child in coarse.children(index).unwrap() {
                cells.push(GridCell {
                    level: 3,
                    index: child,
                });
                mixed_masses.push(masses[index as usize] / 8.0);
            }
        } else {
            cells.push(GridCell { level: 2, index });
            mixed_masses.push(masses[index as usize]);
        }
    }
    let mixed = Distribution::from_cells(cells, mixed_masses).unwrap();
    let elsewhere = random_rotations(20, 22);
    for q in elsewhere.iter().chain([&gt]) {
        assert!((llh(&dense, &[*q]).unwrap() - llh(&mixed, &[*q]).unwrap()).abs() < 1e-9);
    }
    let (a, b) = (maad(&dense, &[gt]).unwrap(), maad(&mixed, &[gt]).unwrap());
    assert!((a - b).abs() < 3.0, "{a} vs {b}");
    let (a, b) = (
        recall_maad(&dense, &[gt], RECALL_THRESHOLD).unwrap(),
        recall_maad(&mixed, &[gt], RECALL_THRESHOLD).unwrap(),
    );
    assert!((a - b).abs() < 15.0, "{a} vs {b}");
}

#[test]
fn bad_distributions_are_rejected() {
    let grid = Grid::new(0).unwrap();
    let n = grid.len() as usize;
    assert!(matches!(
        Distribution::dense(&grid, vec![1.0 / 71.0; 71]),
        Err(MetricsError::LengthMismatch { .. })
    ));
    let mut masses = vec![1.0 / n as f64; n];
    masses[3] = f64::NAN;
    assert!(matches!(
        Distribution::dense(&grid, masses),
        Err(MetricsError::InvalidMass { position: 3, .. })
    ));
    assert!(matches!(
        Distribution::dense(&grid, vec![1.0; n]),
        Err(MetricsError::MassSum { .. })
    ));
    let cells = vec![GridCell { level: 0, index: 0 }; 2];
    assert!(matches!(
        Distribution::from_cells(cells, vec![0.5, 0.5]),
        Err(MetricsError::DuplicateCell { .. })
    ));
    let gaps = vec![
        GridCell { level: 0, index: 0 },
        GridCell { level: 0, index: 1 },
    ];
    assert!(matches!(
        Distribution::from_cells(gaps, vec![0.5, 0.5]),
        Err(MetricsError::NotAPartition { .. })
    ));
    let uniform = Distribution::uniform(&grid);
    assert!(matches!(
        llh(&uniform, &[]),
        Err(MetricsError::EmptyGroundTruth)
    ));
    assert!(matches!(
        maad(&uniform, &[]),
        Err(MetricsError::EmptyGroundTruth)
    ));
}

#[test]
fn bop_symmetry_fields_round_trip_and_expand() {
    // T-LESS obj_000001-like entry: a continuous z axis plus a flip about x.
    let info = serde_json::json!({
        "diameter": 63.5,
        "symmetries_continuous": [{"axis": [0, 0, 1], "offset": [0, 0, 0]}],
        "symmetries_discrete": [[1, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1]]
    });
    let group = SymmetryGroup::from_bop_json(&info).unwrap();
    assert_eq!(group.discrete.len(), 1);
    assert_eq!(group.continuous.len(), 1);
    assert_eq!(
        SymmetryGroup::from_bop_json(&group.to_bop_json()).unwrap(),
        group
    );
    let pose = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0);
    let set = group.expand(&pose);
    assert_eq!(set.len(), 400);
    // Every member maps the symmetry axis to the same camera direction, up to the flip.
    let axis = pose * Vector3::z();
    for q in &set {
        assert!((q * Vector3::z()).dot(&axis).abs() > 1.0 - 1e-9);
    }
}

#[test]
fn malformed_bop_symmetries_name_the_field() {
    let cases = [
        (
            serde_json::json!({"symmetries_discrete": [[1, 0, 0]]}),
            "symmetries_discrete[0]",
        ),
        (
            serde_json::json!({"symmetries_discrete": [[2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]}),
            "symmetries_discrete[0]",
        ),
        (
            serde_json::json!({"symmetries_continuous": [{"axis": [0, 0, 0], "offset": [0, 0, 0]}]}),
            "symmetries_continuous[0].axis",
        ),
        (
            serde_json::json!({"symmetries_continuous": [{"axis": [0, 0, 1]}]}),
            "symmetries_continuous[0].offset",
        ),
        (
            serde_json::json!({"symmetries_continuous": {"axis": [0, 0, 1]}}),
            "symmetries_continuous",
        ),
        (
            serde_json::json!({"symmetries_discrete": [["a", 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]}),
            "symmetries_discrete[0]",
        ),
    ];
    for (info, field) in cases {
        match SymmetryGroup::from_bop_json(&info) {
            Err(MetricsError::InvalidSymmetry { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{info}: expected an error on {field}, got {other:?}"),
        }
    }
}
