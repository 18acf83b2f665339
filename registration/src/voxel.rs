//! Voxel-grid downsampling: one point per occupied voxel, at the centroid of its points.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::error::positive_metres;
use crate::{PointCloud, RegistrationError};

/// Replaces the points in each occupied cube of side `voxel_size` (metres, grid aligned with the
/// origin) by their centroid; normals, if present, by their normalised mean (or the first
/// normal of the voxel where they cancel out).
///
/// The output is ordered by voxel (x, then y, then z index), so it does not depend on the input
/// order or the thread count.
///
/// ```
/// use nalgebra::Point3;
/// use registration::{PointCloud, downsample_voxel};
/// let cloud = PointCloud::new(vec![Point3::new(0.001, 0.0, 0.0), Point3::new(0.003, 0.0, 0.0)])?;
/// let down = downsample_voxel(&cloud, 0.005)?;
/// assert_eq!(down.len(), 1);
/// assert!((down.points()[0].x - 0.002).abs() < 1e-7);
/// # Ok::<(), registration::RegistrationError>(())
/// ```
pub fn downsample_voxel(
    cloud: &PointCloud,
    voxel_size: f32,
) -> Result<PointCloud, RegistrationError> {
    positive_metres("voxel_size", voxel_size)?;
    if cloud.is_empty() {
        return Err(RegistrationError::EmptyCloud { cloud: "input" });
    }
    let points = cloud.points();
    // `as` saturates, so far-away points share the outermost voxel instead of overflowing.
    let key = |p: &Point3<f32>| {
        p.coords
            .map(|c| (f64::from(c) / f64::from(voxel_size)).floor() as i64)
    };
    let mut order: Vec<(Vector3<i64>, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    order.par_sort_unstable_by(|a, b| (a.0.x, a.0.y, a.0.z, a.1).cmp(&(b.0.x, b.0.y, b.0.z, b.1)));

    let normals = cloud.normals();
    let mut out_points = Vec::new();
    let mut out_normals = normals.map(|_| Vec::new());
    for voxel in order.chunk_by(|a, b| a.0 == b.0) {
        let sum = voxel.iter().fold(Vector3::<f64>::zeros(), |s, &(_, i)| {
            s + points[i as usize].coords.cast()
        });
        out_points.push(Point3::from((sum / voxel.len() as f64).cast::<f32>()));
        if let (Some(normals), Some(out)) = (normals, out_normals.as_mut()) {
            let first = normals[voxel[0].1 as usize];
            let mean: Vector3<f32> = voxel.iter().map(|&(_, i)| normals[i as usize]).sum();
            out.push(mean.try_normalize(1e-6).unwrap_or(first));
        }
    }
    Ok(PointCloud::from_valid(out_points, out_normals))
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        #[test]
        fn one_point_per_voxel_at_its_centroid(
            coords in prop::collection::vec((-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0), 1..400),
            voxel_size in 0.01f32..0.5,
        ) {
            let points: Vec<_> = coords.iter().map(|&(x, y, z)| Point3::new(x, y, z)).collect();
            let cloud = PointCloud::new(points.clone()).unwrap();
            let down = downsample_voxel(&cloud, voxel_size).unwrap();
            // The voxel of a point: the cube of side `voxel_size` from the origin holding it.
            let voxel = |p: &Point3<f32>| p.coords.map(|c| (f64::from(c) / f64::from(voxel_size)).floor() as i64);
            let mut members: std::collections::BTreeMap<(i64, i64, i64), Vec<Point3<f32>>> = Default::default();
            for p in &points {
                let v = voxel(p);
                members.entry((v.x, v.y, v.z)).or_default().push(*p);
            }
            // One point per occupied voxel, in voxel order (x, then y, then z index).
            prop_assert_eq!(down.len(), members.len());
            // Each output point is its voxel's centroid (summed here in f64, point by point),
            // up to f32 rounding: the centre of the points' box, `(min + max) / 2`, is not.
            for (q, voxel_points) in down.points().iter().zip(members.values()) {
                let sum = voxel_points.iter().fold(Vector3::<f64>::zeros(), |s, p| s + p.coords.cast());
                let centroid = sum / voxel_points.len() as f64;
                for axis in 0..3 {
                    prop_assert!((f64::from(q[axis]) - centroid[axis]).abs() < 1e-6, "{q} is not the centroid {centroid} of {voxel_points:?}");
                }
            }
            // Input order does not matter.
            let reversed = PointCloud::new(points.into_iter().rev().collect()).unwrap();
            let down_reversed = downsample_voxel(&reversed, voxel_size).unwrap();
            for (a, b) in down.points().iter().zip(down_reversed.points()) {
                prop_assert!((a - b).norm() < 1e-6);
            }
        }
    }

    #[test]
    fn bad_voxel_size_and_empty_cloud_are_errors() {
        let cloud = PointCloud::new(vec![Point3::origin()]).unwrap();
        for size in [0.0, -1.0, f32::NAN] {
            assert!(matches!(
                downsample_voxel(&cloud, size),
                Err(RegistrationError::InvalidOption { .. })
            ));
        }
        let empty = PointCloud::new(vec![]).unwrap();
        assert!(matches!(
            downsample_voxel(&empty, 0.1),
            Err(RegistrationError::EmptyCloud { .. })
        ));
    }

    #[test]
    fn normals_are_averaged() {
        let cloud = PointCloud::new(vec![Point3::origin(), Point3::new(0.01, 0.0, 0.0)])
            .unwrap()
            .with_normals(vec![Vector3::x(), Vector3::y()])
            .unwrap();
        let down = downsample_voxel(&cloud, 1.0).unwrap();
        let n = down.normals().unwrap()[0];
        assert!((n - Vector3::new(1.0, 1.0, 0.0).normalize()).norm() < 1e-6);
    }
}
