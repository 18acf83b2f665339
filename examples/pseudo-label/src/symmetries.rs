//! The model's own symmetries, found from its mesh, and the choice of diverse pose sets.
//!
//! A random initial pose makes FGR land on *some* member of an object's symmetry set, but not
//! on an even spread of them (see the crate README's labelling section for the measurement).
//! So once one pose is accepted, the other members are reached by re-seeding ICP from that
//! pose composed with each self-symmetry of the model, which is found once per object here:
//! ICP of the model cloud onto itself from every rotation of a level-0 grid (72) about its
//! centroid, keeping the motions whose surface residual is
//! tiny. This uses the mesh alone (never a ground-truth pose) and works for any mesh, whatever
//! its symmetries (none, discrete, continuous or approximate).
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use rayon::prelude::*;
use registration::{IcpOptions, PreparedCloud, downsample_voxel, refine_icp};
use so3_grid::{Grid, geodesic_distance};

/// Two symmetries closer than this (radians, 5°) are the same: ICP may stop a little short of
/// an exact symmetry where a face slides within its own plane.
const SAME_SYMMETRY: f64 = 5.0f64 * std::f64::consts::PI / 180.0;

/// The mean point-to-plane distance (metres) of the points `pose · source` to `target`, each point's
/// distance capped at `cap` and points with no target point within `2 · cap` counted as `cap`:
/// 0 when the moved points lie on the target's surface, whatever the sampling.
pub fn surface_residual(
    source: &[Point3<f32>],
    target: &PreparedCloud,
    pose: &Isometry3<f64>,
    cap: f32,
) -> f64 {
    let Some(normals) = target.cloud.normals() else {
        return f64::from(cap);
    };
    let pose = pose.cast::<f32>();
    let total: f64 = source
        .par_iter()
        .map(|p| {
            let moved = pose * p;
            let distance = match target
                .index
                .nearest_within_radius(&[moved.x, moved.y, moved.z], 2.0 * cap)
            {
                Some(n) => {
                    let q = target.cloud.points()[n.index as usize];
                    normals[n.index as usize].dot(&(moved - q)).abs().min(cap)
                }
                None => cap,
            };
            f64::from(distance)
        })
        .sum();
    total / source.len().max(1) as f64
}

/// The rigid motions `S` (model frame, metres) with `S · model ≈ model`, identity first, the
/// others by increasing surface residual, no two within 5°. `voxel` is the model cloud's voxel
/// size: a motion is kept when the surface residual after ICP is below `0.08 · voxel`.
pub fn discover_symmetries(model: &PreparedCloud, voxel: f32) -> Vec<Isometry3<f64>> {
    let Some(centroid) = model.cloud.centroid() else {
        return vec![Isometry3::identity()];
    };
    let to_centre = Translation3::from(-centroid.coords);
    let back = Translation3::from(centroid.coords);
    let grid = Grid::new(0).expect("level 0 exists");
    let coarse = IcpOptions {
        max_correspondence_distance: 4.0 * voxel,
        max_iterations: 15,
        ..IcpOptions::default()
    };
    let fine = IcpOptions {
        max_correspondence_distance: 1.5 * voxel,
        max_iterations: 30,
        ..IcpOptions::default()
    };
    // The moving copy at twice the voxel: a sixth of the points, the same surface.
    let Ok(source) = downsample_voxel(&model.cloud, 2.0 * voxel) else {
        return vec![Isometry3::identity()];
    };
    let mut found: Vec<(Isometry3<f64>, f64)> = grid
        .rotations()
        .par_iter()
        .map(|rotation| {
            let start =
                back * Isometry3::from_parts(Translation3::identity(), *rotation) * to_centre;
            let refine = |pose: &Isometry3<f64>, options: &IcpOptions| {
                refine_icp(&source, &model.cloud, &model.index, pose, options)
                    .ok()
                    .map(|a| a.pose)
            };
            let pose = refine(&start, &coarse).and_then(|p| refine(&p, &fine))?;
            let residual = surface_residual(model.cloud.points(), model, &pose, voxel);
            (residual < 0.08 * f64::from(voxel)).then_some((pose, residual))
        })
        .flatten()
        .collect();
    // The best of each cluster first (stable: ties keep grid order).
    found.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut symmetries = vec![Isometry3::identity()];
    for (pose, _) in found {
        if symmetries
            .iter()
            .all(|s| geodesic_distance(&s.rotation, &pose.rotation) > SAME_SYMMETRY)
        {
            symmetries.push(pose);
        }
    }
    symmetries
}

/// Up to `count` of `rotations` spread as evenly as possible: the first, then repeatedly the
/// one farthest from all chosen (farthest-point sampling). Indices into `rotations`.
pub fn spread(rotations: &[UnitQuaternion<f64>], count: usize) -> Vec<usize> {
    if rotations.is_empty() || count == 0 {
        return Vec::new();
    }
    let mut chosen = vec![0];
    let mut nearest: Vec<f64> = rotations
        .iter()
        .map(|r| geodesic_distance(r, &rotations[0]))
        .collect();
    while chosen.len() < count.min(rotations.len()) {
        let (next, &distance) = nearest
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
            .expect("not empty");
        if distance <= 0.0 {
            break;
        }
        chosen.push(next);
        for (d, r) in nearest.iter_mut().zip(rotations) {
            *d = d.min(geodesic_distance(r, &rotations[next]));
        }
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// Farthest-point sampling keeps the first rotation, never picks one twice, and its
        /// choice covers the set: every rotation is within the smallest gap between chosen ones.
        #[test]
        fn spread_is_distinct_and_covering(seed in 0u64..1000, count in 1usize..12) {
            let rotations = so3_grid::random_rotations(40, seed);
            let chosen = spread(&rotations, count);
            prop_assert_eq!(chosen[0], 0);
            prop_assert_eq!(chosen.len(), count.min(40));
            let mut sorted = chosen.clone();
            sorted.sort_unstable();
            sorted.dedup();
            prop_assert_eq!(sorted.len(), chosen.len());
            let gap = chosen.iter().enumerate().flat_map(|(i, &a)| {
                chosen[i + 1..].iter().map(move |&b| (a, b))
            }).map(|(a, b)| geodesic_distance(&rotations[a], &rotations[b]))
            .fold(f64::INFINITY, f64::min);
            for r in &rotations {
                let reach = chosen.iter().map(|&c| geodesic_distance(r, &rotations[c])).fold(f64::INFINITY, f64::min);
                prop_assert!(reach <= gap + 1e-12);
            }
        }
    }

    #[test]
    fn spread_of_a_circle_is_even() {
        let circle: Vec<_> = (0..360)
            .map(|d| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), f64::from(d).to_radians()))
            .collect();
        let chosen = spread(&circle, 4);
        let mut angles: Vec<usize> = chosen.clone();
        angles.sort_unstable();
        assert_eq!(angles, vec![0, 90, 180, 270]);
    }
}
