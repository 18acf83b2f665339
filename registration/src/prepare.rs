//! Preprocessing shared by FGR and ICP: downsample, normals, FPFH and the search trees, computed
//! once per cloud and reused (a model is registered against many observed clouds).

use nalgebra::Point3;

use crate::fpfh::{Fpfh, FpfhOptions, compute_fpfh};
use crate::neighbours::PointIndex;
use crate::normals::{NormalOptions, NormalOrientation, estimate_normals};
use crate::voxel::downsample_voxel;
use crate::{PointCloud, RegistrationError};

/// Options of [`prepare_cloud`]; [`PrepareOptions::for_voxel`] derives them from a voxel size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrepareOptions {
    /// Voxel size of the downsampling, metres.
    pub voxel_size: f32,
    /// Normal estimation, used when the cloud has no normals or `keep_normals` is false.
    pub normals: NormalOptions,
    /// Keep the normals the input cloud carries (averaged per voxel) instead of estimating them.
    pub keep_normals: bool,
    /// FPFH neighbourhood.
    pub fpfh: FpfhOptions,
}

impl PrepareOptions {
    /// Open3D's tutorial choice: normals over 2 voxels (30 neighbours), FPFH over 5 voxels (100
    /// neighbours), normals towards a camera at the origin.
    pub fn for_voxel(voxel_size: f32) -> Self {
        Self {
            voxel_size,
            normals: NormalOptions {
                radius: 2.0 * voxel_size,
                max_neighbours: 30,
                orientation: NormalOrientation::TowardsViewpoint(Point3::origin()),
            },
            keep_normals: true,
            fpfh: FpfhOptions {
                radius: 5.0 * voxel_size,
                max_neighbours: 100,
            },
        }
    }

    /// The same options with normals oriented by `orientation`.
    pub fn oriented(mut self, orientation: NormalOrientation) -> Self {
        self.normals.orientation = orientation;
        self
    }
}

impl Default for PrepareOptions {
    /// [`PrepareOptions::for_voxel`] at 5 mm.
    fn default() -> Self {
        Self::for_voxel(0.005)
    }
}

/// A downsampled cloud with normals, its FPFH features and a search tree over its points.
#[derive(Debug)]
pub struct PreparedCloud {
    /// The downsampled cloud, with normals.
    pub cloud: PointCloud,
    /// One FPFH descriptor per point of `cloud`.
    pub features: Vec<Fpfh>,
    /// Search tree over `cloud`'s points.
    pub index: PointIndex,
}

impl PreparedCloud {
    /// The same cloud, indexed with the grid of [`PointIndex::with_nearest_grid`] as well: for
    /// a cloud that many ICP runs align to, such as a model.
    pub fn with_nearest_grid(mut self) -> Self {
        self.index.add_nearest_grid(self.cloud.points());
        self
    }
}

/// Downsamples `cloud`, gives it normals and FPFH features, and indexes both.
///
/// Errors: an empty cloud, bad options, a cloud (after downsampling) with fewer than 3 points or
/// whose points are collinear or coplanar (no unique pose can be registered against it).
pub fn prepare_cloud(
    cloud: &PointCloud,
    options: &PrepareOptions,
) -> Result<PreparedCloud, RegistrationError> {
    let down = downsample_voxel(cloud, options.voxel_size)?;
    if down.len() < 3 {
        return Err(RegistrationError::TooFewPoints {
            stage: "registration",
            needed: 3,
            got: down.len(),
        });
    }
    down.check_not_degenerate("input")?;
    let index = PointIndex::from_points(down.points());
    let down = if options.keep_normals && down.normals().is_some() {
        down
    } else {
        estimate_normals(&down, &index, &options.normals)?
    };
    let features = compute_fpfh(&down, &index, &options.fpfh)?;
    Ok(PreparedCloud {
        cloud: down,
        features,
        index,
    })
}
