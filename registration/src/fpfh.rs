//! Fast Point Feature Histograms (Rusu, Blodow, Beetz, ICRA 2009), 33 bins.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::error::{at_least_one, positive_metres};
use crate::neighbours::{Neighbour, PointIndex};
use crate::{PointCloud, RegistrationError};

/// Bins per angular feature; a descriptor is three such histograms side by side.
const BINS: usize = 11;

/// Length of an FPFH descriptor.
pub const FPFH_LEN: usize = 3 * BINS;

/// One FPFH descriptor: three 11-bin histograms (α, φ, θ of the paper), each summing to 200
/// (100 from the point's own SPFH, 100 from its weighted neighbours) where it has neighbours.
pub type Fpfh = [f32; FPFH_LEN];

/// Options of [`compute_fpfh`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FpfhOptions {
    /// Neighbourhood radius in metres (Open3D's tutorial: 5 × voxel size).
    pub radius: f32,
    /// At most this many nearest neighbours within `radius` (Open3D's tutorial: 100).
    pub max_neighbours: usize,
}

impl Default for FpfhOptions {
    /// 2.5 cm radius (5 mm voxels), 100 neighbours.
    fn default() -> Self {
        Self {
            radius: 0.025,
            max_neighbours: 100,
        }
    }
}

/// Computes one FPFH descriptor per point of `cloud` (which must have normals; `index` must
/// index its points), in parallel, deterministically.
///
/// SPFH(p) histograms the Darboux-frame angles (α, φ, θ; paper Sec. III, Eq. 1–2) of p with each
/// neighbour; FPFH(p) = SPFH(p) + Σ_k SPFH(p_k) / ω_k with each histogram renormalised, where
/// ω_k is the squared distance (as in PCL and Open3D; paper Eq. 3 uses a distance).
pub fn compute_fpfh(
    cloud: &PointCloud,
    index: &PointIndex,
    options: &FpfhOptions,
) -> Result<Vec<Fpfh>, RegistrationError> {
    let normals = cloud
        .normals()
        .ok_or(RegistrationError::MissingNormals { stage: "FPFH" })?;
    if cloud.is_empty() {
        return Err(RegistrationError::EmptyCloud { cloud: "input" });
    }
    positive_metres("radius", options.radius)?;
    let max_neighbours = at_least_one("max_neighbours", options.max_neighbours)?;
    let points = cloud.points();
    let neighbourhoods: Vec<Vec<Neighbour>> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let mut found = Vec::new();
            index.nearest_within(&[p.x, p.y, p.z], options.radius, max_neighbours, &mut found);
            found.retain(|n| n.index as usize != i);
            found
        })
        .collect();
    let spfh: Vec<Fpfh> = (0..points.len())
        .into_par_iter()
        .map(|i| simplified_histogram(points, normals, i, &neighbourhoods[i]))
        .collect();
    Ok((0..points.len())
        .into_par_iter()
        .map(|i| {
            let mut weighted = [0f32; FPFH_LEN];
            for n in neighbourhoods[i]
                .iter()
                .filter(|n| n.distance_squared > 0.0)
            {
                let weight = n.distance_squared.recip();
                for (sum, value) in weighted.iter_mut().zip(&spfh[n.index as usize]) {
                    *sum += weight * value;
                }
            }
            // Each weighted histogram rescaled to sum to 100, added to the point's own SPFH.
            let mut out = spfh[i];
            for (out, weighted) in out.chunks_exact_mut(BINS).zip(weighted.chunks_exact(BINS)) {
                let sum: f32 = weighted.iter().sum();
                if sum > 0.0 {
                    let scale = 100.0 / sum;
                    for (o, w) in out.iter_mut().zip(weighted) {
                        *o += w * scale;
                    }
                }
            }
            out
        })
        .collect())
}

/// SPFH of point `i`: each angle histogrammed over its neighbours, 100 in all per histogram.
fn simplified_histogram(
    points: &[Point3<f32>],
    normals: &[Vector3<f32>],
    i: usize,
    neighbours: &[Neighbour],
) -> Fpfh {
    let mut histogram = [0f32; FPFH_LEN];
    if neighbours.is_empty() {
        return histogram;
    }
    let increment = 100.0 / neighbours.len() as f32;
    let bin = |value: f32, low: f32, high: f32| {
        (((value - low) / (high - low) * BINS as f32).floor() as usize).min(BINS - 1)
    };
    for n in neighbours {
        let j = n.index as usize;
        if let Some([alpha, phi, theta]) =
            pair_features(&points[i], &normals[i], &points[j], &normals[j])
        {
            histogram[bin(theta, -std::f32::consts::PI, std::f32::consts::PI)] += increment;
            histogram[BINS + bin(alpha, -1.0, 1.0)] += increment;
            histogram[2 * BINS + bin(phi, -1.0, 1.0)] += increment;
        } else {
            // Coincident points or parallel normals along the baseline: all angles are zero.
            histogram[bin(0.0, -std::f32::consts::PI, std::f32::consts::PI)] += increment;
            histogram[BINS + bin(0.0, -1.0, 1.0)] += increment;
            histogram[2 * BINS + bin(0.0, -1.0, 1.0)] += increment;
        }
    }
    histogram
}

/// The Darboux-frame features of a point pair (paper Eq. 1–2): α = v·n_t, φ = u·(p_t − p_s)/d,
/// θ = atan2(w·n_t, u·n_t), with the source chosen as the point whose normal makes the smaller
/// angle with the baseline (so the features do not depend on the pair's order).
fn pair_features(
    p1: &Point3<f32>,
    n1: &Vector3<f32>,
    p2: &Point3<f32>,
    n2: &Vector3<f32>,
) -> Option<[f32; 3]> {
    let baseline = p2 - p1;
    let distance = baseline.norm();
    if distance == 0.0 {
        return None;
    }
    let (angle1, angle2) = (n1.dot(&baseline) / distance, n2.dot(&baseline) / distance);
    let (u, target, baseline, phi) = if angle1.abs() >= angle2.abs() {
        (n1, n2, baseline, angle1)
    } else {
        (n2, n1, -baseline, -angle2)
    };
    let v = baseline.cross(u).try_normalize(0.0)?;
    let w = u.cross(&v);
    Some([v.dot(target), phi, w.dot(target).atan2(u.dot(target))])
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, UnitQuaternion};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::normals::{NormalOptions, NormalOrientation, estimate_normals};

    /// A bumpy, non-symmetric surface patch.
    fn surface(count: usize, seed: u64) -> Vec<Point3<f32>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..count)
            .map(|_| {
                let (x, y): (f32, f32) = (rng.random::<f32>() * 0.2, rng.random::<f32>() * 0.2);
                Point3::new(
                    x,
                    y,
                    0.02 * (30.0 * x).sin() * (17.0 * y + 1.0).cos() + 0.5 * x * x,
                )
            })
            .collect()
    }

    fn describe(points: &[Point3<f32>], viewpoint: Point3<f32>) -> Vec<Fpfh> {
        let cloud = PointCloud::new(points.to_vec()).unwrap();
        let index = PointIndex::from_points(points);
        let normals = NormalOptions {
            radius: 0.015,
            max_neighbours: 30,
            orientation: NormalOrientation::TowardsViewpoint(viewpoint),
        };
        let with = estimate_normals(&cloud, &index, &normals).unwrap();
        compute_fpfh(
            &with,
            &index,
            &FpfhOptions {
                radius: 0.03,
                max_neighbours: 100,
            },
        )
        .unwrap()
    }

    #[test]
    fn descriptor_of_a_moved_cloud_equals_the_original() {
        let points = surface(3000, 1);
        let pose = Isometry3::from_parts(
            nalgebra::Translation3::new(0.3, -0.2, 0.7),
            UnitQuaternion::from_euler_angles(0.7, -1.1, 2.3),
        )
        .cast::<f32>();
        let moved: Vec<_> = points.iter().map(|p| pose * p).collect();
        let viewpoint = Point3::new(0.1, 0.1, 1.0);
        let original = describe(&points, viewpoint);
        let rotated = describe(&moved, pose * viewpoint);
        let mut worst = 0f32;
        for (a, b) in original.iter().zip(&rotated) {
            let difference: f32 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
            worst = worst.max(difference / a.iter().sum::<f32>());
        }
        // Rounding can move a pair across a bin edge: a tiny fraction of the mass.
        assert!(worst < 0.02, "relative L1 difference {worst}");
    }

    #[test]
    fn histograms_sum_to_200_and_features_discriminate() {
        let features = describe(&surface(2000, 2), Point3::new(0.1, 0.1, 1.0));
        for f in &features {
            for h in 0..3 {
                let sum: f32 = f[h * BINS..(h + 1) * BINS].iter().sum();
                assert!((sum - 200.0).abs() < 1e-2, "histogram {h} sums to {sum}");
            }
        }
        let l1 = |a: &Fpfh, b: &Fpfh| a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>();
        let distinct = features
            .iter()
            .filter(|f| l1(f, &features[0]) > 30.0)
            .count();
        assert!(distinct > features.len() / 4);
    }

    #[test]
    fn pair_features_do_not_depend_on_pair_order() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let mut v = || {
                Vector3::new(
                    rng.random::<f32>() - 0.5,
                    rng.random::<f32>() - 0.5,
                    rng.random::<f32>() - 0.5,
                )
            };
            let (p1, p2) = (Point3::from(v()), Point3::from(v()));
            let (n1, n2) = (v().normalize(), v().normalize());
            let a = pair_features(&p1, &n1, &p2, &n2).unwrap();
            let b = pair_features(&p2, &n2, &p1, &n1).unwrap();
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-4, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn missing_normals_is_an_error() {
        let points = surface(10, 4);
        let cloud = PointCloud::new(points.clone()).unwrap();
        let err = compute_fpfh(
            &cloud,
            &PointIndex::from_points(&points),
            &FpfhOptions::default(),
        );
        assert!(matches!(err, Err(RegistrationError::MissingNormals { .. })));
    }
}
