//! The point-cloud type: positions in metres, optional unit normals.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, SymmetricEigen, UnitQuaternion, Vector3};

use crate::RegistrationError;

/// A point cloud: positions (metres, f32) and, optionally, one unit normal per point.
///
/// Constructed through [`PointCloud::new`] / [`PointCloud::with_normals`], which reject NaN and
/// infinite coordinates, so every cloud in this crate is finite.
#[derive(Debug, Clone, PartialEq)]
pub struct PointCloud {
    points: Vec<Point3<f32>>,
    normals: Option<Vec<Vector3<f32>>>,
}

impl PointCloud {
    /// A cloud of `points`, without normals. An empty cloud is allowed; stages that need points
    /// say so with [`RegistrationError::EmptyCloud`].
    pub fn new(points: Vec<Point3<f32>>) -> Result<Self, RegistrationError> {
        if let Some(index) = points
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(RegistrationError::NonFinite {
                field: "points",
                index,
            });
        }
        Ok(Self {
            points,
            normals: None,
        })
    }

    /// The same cloud with one normal per point. Normals are normalised to unit length; a zero
    /// or non-finite normal is an error.
    pub fn with_normals(mut self, normals: Vec<Vector3<f32>>) -> Result<Self, RegistrationError> {
        if normals.len() != self.points.len() {
            return Err(RegistrationError::NormalCount {
                points: self.points.len(),
                normals: normals.len(),
            });
        }
        let mut unit = normals;
        for (index, n) in unit.iter_mut().enumerate() {
            let length = n.norm();
            if !(length.is_finite() && length > 0.0) {
                return Err(RegistrationError::NonFinite {
                    field: "normals",
                    index,
                });
            }
            *n /= length;
        }
        self.normals = Some(unit);
        Ok(self)
    }

    /// Built from parts already known to be valid (finite points, unit normals of equal count).
    pub(crate) fn from_valid(points: Vec<Point3<f32>>, normals: Option<Vec<Vector3<f32>>>) -> Self {
        debug_assert!(normals.as_ref().is_none_or(|n| n.len() == points.len()));
        Self { points, normals }
    }

    /// The positions.
    pub fn points(&self) -> &[Point3<f32>] {
        &self.points
    }

    /// The unit normals, if the cloud has them.
    pub fn normals(&self) -> Option<&[Vector3<f32>]> {
        self.normals.as_deref()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The cloud moved by a rigid transform (`pose` maps this cloud's frame into the new one);
    /// normals are rotated.
    pub fn transformed(&self, pose: &Isometry3<f64>) -> Self {
        let pose = pose.cast::<f32>();
        let points = self.points.iter().map(|p| pose * p).collect();
        let normals = self
            .normals
            .as_ref()
            .map(|normals| normals.iter().map(|n| pose.rotation * n).collect());
        Self { points, normals }
    }

    /// Centroid (f64 accumulation). `None` for an empty cloud.
    pub fn centroid(&self) -> Option<Point3<f64>> {
        centroid(&self.points)
    }

    /// The frame of the cloud's principal axes: origin at the centroid, columns of the rotation
    /// the covariance's eigenvectors (right-handed, in nalgebra's eigenvalue order, which is not
    /// sorted). `None` for an empty cloud.
    pub fn principal_frame(&self) -> Option<Isometry3<f64>> {
        let (mean, covariance) = covariance(&self.points)?;
        let mut axes = SymmetricEigen::new(covariance).eigenvectors;
        if axes.determinant() < 0.0 {
            axes.column_mut(2).neg_mut();
        }
        let rotation = Rotation3::from_matrix_unchecked(axes);
        Some(Isometry3::from_parts(
            mean.coords.into(),
            UnitQuaternion::from_rotation_matrix(&rotation),
        ))
    }

    /// Fails with [`RegistrationError::Degenerate`] when all points lie (to within a relative
    /// 1e-3 of the cloud's extent) on a line or a plane: no rigid pose is unique then.
    pub fn check_not_degenerate(&self, cloud: &'static str) -> Result<(), RegistrationError> {
        if self.points.is_empty() {
            return Err(RegistrationError::EmptyCloud { cloud });
        }
        let spread = principal_spread(&self.points);
        let largest = spread[2].max(f64::MIN_POSITIVE);
        // Eigenvalues are variances: compare standard deviations.
        let relative = |value: f64| (value.max(0.0) / largest).sqrt();
        if relative(spread[1]) < 1e-3 {
            Err(RegistrationError::Degenerate {
                cloud,
                shape: "collinear",
            })
        } else if relative(spread[0]) < 1e-3 {
            Err(RegistrationError::Degenerate {
                cloud,
                shape: "coplanar",
            })
        } else {
            Ok(())
        }
    }
}

/// Centroid of `points`, accumulated in f64.
pub(crate) fn centroid(points: &[Point3<f32>]) -> Option<Point3<f64>> {
    if points.is_empty() {
        return None;
    }
    let sum = points
        .iter()
        .fold(Vector3::zeros(), |sum, p| sum + p.coords.cast::<f64>());
    Some(Point3::from(sum / points.len() as f64))
}

/// The centroid of `points` and their covariance (f64). `None` when empty.
fn covariance(points: &[Point3<f32>]) -> Option<(Point3<f64>, Matrix3<f64>)> {
    let mean = centroid(points)?;
    let mut covariance = Matrix3::zeros();
    for p in points {
        let d = p.coords.cast::<f64>() - mean.coords;
        covariance += d * d.transpose();
    }
    Some((mean, covariance / points.len() as f64))
}

/// The centroid of `points` and their RMS distance from it; `None` for no points.
pub(crate) fn centre_and_radius(points: &[Point3<f32>]) -> Option<(Point3<f64>, f64)> {
    covariance(points).map(|(mean, covariance)| (mean, covariance.trace().sqrt()))
}

/// Eigenvalues of the covariance of `points`, ascending (f64).
fn principal_spread(points: &[Point3<f32>]) -> [f64; 3] {
    let Some((_, covariance)) = covariance(points) else {
        return [0.0; 3];
    };
    let mut values: Vec<f64> = SymmetricEigen::new(covariance)
        .eigenvalues
        .iter()
        .copied()
        .collect();
    values.sort_by(f64::total_cmp);
    [values[0], values[1], values[2]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The principal frame sits at the centroid, is a proper rotation, and diagonalises the
        /// covariance: its axes are the cloud's principal axes.
        #[test]
        fn principal_frame_diagonalises_the_covariance(
            axis in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
            angle in 0.0f64..std::f64::consts::PI,
            offset in (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0),
            seed in 0u32..1000,
        ) {
            let turn = UnitQuaternion::from_scaled_axis(Vector3::new(axis.0, axis.1, axis.2) * angle);
            // A cloud stretched 3:2:1 along the turned axes.
            let points: Vec<Point3<f32>> = (0..300u32)
                .map(|i| {
                    let h = |k: u32| ((i.wrapping_mul(2_654_435_761) ^ seed.wrapping_mul(k)) % 1000) as f64 / 1000.0 - 0.5;
                    let local = Vector3::new(3.0 * h(7), 2.0 * h(13), h(29));
                    let p = turn * local;
                    Point3::new(p.x as f32 + offset.0, p.y as f32 + offset.1, p.z as f32 + offset.2)
                })
                .collect();
            let cloud = PointCloud::new(points.clone()).unwrap();
            let frame = cloud.principal_frame().unwrap();
            let centroid = cloud.centroid().unwrap();
            prop_assert!((frame.translation.vector - centroid.coords).norm() < 1e-9);
            let rotation = frame.rotation.to_rotation_matrix().into_inner();
            prop_assert!((rotation.determinant() - 1.0).abs() < 1e-9);
            let (_, c) = covariance(&points).unwrap();
            let diagonal = rotation.transpose() * c * rotation;
            let scale = c.norm();
            for (i, j) in [(0, 1), (0, 2), (1, 2)] {
                prop_assert!(diagonal[(i, j)].abs() < 1e-9 * scale.max(1.0), "{diagonal}");
            }
        }
    }

    #[test]
    fn rejects_non_finite_points_and_normals() {
        let err = PointCloud::new(vec![Point3::origin(), Point3::new(f32::NAN, 0.0, 0.0)]);
        assert!(matches!(
            err,
            Err(RegistrationError::NonFinite {
                field: "points",
                index: 1
            })
        ));
        let cloud = PointCloud::new(vec![Point3::origin()]).unwrap();
        let err = cloud.clone().with_normals(vec![Vector3::zeros()]);
        assert!(matches!(
            err,
            Err(RegistrationError::NonFinite {
                field: "normals",
                index: 0
            })
        ));
        let err = cloud.with_normals(vec![]);
        assert!(matches!(
            err,
            Err(RegistrationError::NormalCount {
                points: 1,
                normals: 0
            })
        ));
    }

    #[test]
    fn degenerate_shapes_are_named() {
        let line: Vec<_> = (0..10)
            .map(|i| Point3::new(i as f32, 2.0 * i as f32, 0.0))
            .collect();
        let plane: Vec<_> = (0..100)
            .map(|i| Point3::new((i % 10) as f32, (i / 10) as f32, 1.0))
            .collect();
        let mut solid = plane.clone();
        solid.push(Point3::new(0.0, 0.0, 3.0));
        let shape = |points: Vec<Point3<f32>>| match PointCloud::new(points)
            .unwrap()
            .check_not_degenerate("input")
        {
            Err(RegistrationError::Degenerate { shape, .. }) => shape,
            Ok(()) => "solid",
            Err(other) => panic!("{other}"),
        };
        assert_eq!(shape(line), "collinear");
        assert_eq!(shape(plane), "coplanar");
        assert_eq!(shape(solid), "solid");
    }

    #[test]
    fn transform_moves_points_and_rotates_normals() {
        let cloud = PointCloud::new(vec![Point3::new(1.0, 0.0, 0.0)])
            .unwrap()
            .with_normals(vec![Vector3::new(2.0, 0.0, 0.0)])
            .unwrap();
        let pose = Isometry3::new(
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let moved = cloud.transformed(&pose);
        assert!((moved.points()[0] - Point3::new(0.0, 1.0, 1.0)).norm() < 1e-6);
        assert!((moved.normals().unwrap()[0] - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-6);
    }
}
