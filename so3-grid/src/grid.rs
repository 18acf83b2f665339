//! The equivolumetric grid of one level: cell centres, `locate` and `nearest`.
use std::f64::consts::TAU;
use std::ops::Range;
use std::sync::OnceLock;

use nalgebra::{Quaternion, UnitQuaternion};
use rayon::prelude::*;

use crate::GridError;
use crate::cell::{
    bin_count, cell_count, cell_volume, check_cell, check_level, children, decode, encode, parent,
    pixel_count,
};
use crate::hopf::{Section, along_fibre, direction, lon_lat, psi, rotated_z_axis};
use crate::nearest::NearestIndex;

/// The equivolumetric SO(3) grid of one level (Yershova et al. 2010, as used by Implicit-PDF):
/// HEALPix pixel centres (nested, nside = 2^level) for the direction of the rotated z-axis,
/// times `6·2^level` evenly spaced bin centres of the rotation ψ about it (Hopf coordinates
/// with a section per hemisphere, so that every cell is compact; see the crate docs).
///
/// Building a `Grid` costs one HEALPix centre per pixel (`12·4^level`); the rotations are
/// generated on demand ([`Grid::rotations`]) and the tables for [`Grid::nearest`] on its first
/// call.
#[derive(Debug)]
pub struct Grid {
    level: u8,
    /// The section `σ(c)` at every pixel centre `c`, `[w, x, y, z]`.
    pixel_bases: Vec<[f64; 4]>,
    /// `(cos ψ/2, sin ψ/2)` of every bin centre `ψ = (k + ½)·2π/bins`.
    half_psi: Vec<[f64; 2]>,
    nearest: OnceLock<NearestIndex>,
}

impl Grid {
    /// The grid at `level` (0 ..= [`crate::MAX_LEVEL`]).
    pub fn new(level: u8) -> Result<Self, GridError> {
        check_level(level)?;
        let layer = cdshealpix::nested::get(level);
        let pixel_bases = (0..pixel_count(level))
            .into_par_iter()
            .map(|pixel| {
                let (lon, lat) = layer.center(pixel);
                Section::of_pixel(level, pixel).base(&direction(lon, lat))
            })
            .collect();
        let bins = bin_count(level);
        let half_psi = (0..bins)
            .map(|k| {
                let (s, c) = (0.5 * (k as f64 + 0.5) * TAU / bins as f64).sin_cos();
                [c, s]
            })
            .collect();
        Ok(Self {
            level,
            pixel_bases,
            half_psi,
            nearest: OnceLock::new(),
        })
    }

    /// The grid level.
    pub fn level(&self) -> u8 {
        self.level
    }

    /// Number of cells, `72·8^level`.
    pub fn len(&self) -> u64 {
        cell_count(self.level)
    }

    /// Always false: every level has cells.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Volume of each cell, `π² / len()`.
    pub fn cell_volume(&self) -> f64 {
        cell_volume(self.level)
    }

    /// The centre rotation of cell `index`.
    pub fn rotation(&self, index: u64) -> Result<UnitQuaternion<f64>, GridError> {
        check_cell(self.level, index)?;
        Ok(to_unit(self.centre(index)))
    }

    /// All cell centres in cell order, quaternions in the `w ≥ 0` hemisphere.
    ///
    /// Generated in parallel on the current rayon pool; a level-5 grid is 2.4M rotations
    /// (75 MB), so prefer [`Grid::fill_rotations`] into a reused buffer in loops.
    pub fn rotations(&self) -> Vec<UnitQuaternion<f64>> {
        // An indexed parallel collect writes (and page-faults) the fresh buffer on all threads.
        (0..self.len())
            .into_par_iter()
            .map(|index| to_unit(self.centre(index)))
            .collect()
    }

    /// Writes all cell centres (as [`Grid::rotations`]) into `out`, whose length must be
    /// [`Grid::len`]; other lengths write the first `min(len, out.len())` cells.
    pub fn fill_rotations(&self, out: &mut [UnitQuaternion<f64>]) {
        let count = (self.len() as usize).min(out.len());
        let out = &mut out[..count];
        if self.level == 0 {
            for (index, q) in out.iter_mut().enumerate() {
                *q = to_unit(self.centre(index as u64));
            }
            return;
        }
        // Cells come in families of 8 children of one parent: decode the parent once.
        const FAMILIES_PER_TASK: usize = 1024;
        out.par_chunks_mut(8 * FAMILIES_PER_TASK)
            .enumerate()
            .for_each(|(task, chunk)| {
                let first_parent = (task * FAMILIES_PER_TASK) as u64;
                for (offset, family) in chunk.chunks_mut(8).enumerate() {
                    let (pixel, bin) = decode(self.level - 1, first_parent + offset as u64);
                    for (digit, q) in family.iter_mut().enumerate() {
                        let child_pixel = (pixel << 2) | (digit as u64 >> 1);
                        let child_bin = (bin << 1) | (digit as u64 & 1);
                        *q = to_unit(along_fibre(
                            &self.pixel_bases[child_pixel as usize],
                            self.half_psi[child_bin as usize],
                        ));
                    }
                }
            });
    }

    /// The 8 children of cell `index` at `level + 1`.
    pub fn children(&self, index: u64) -> Result<Range<u64>, GridError> {
        children(self.level, index)
    }

    /// The parent of cell `index` at `level − 1`.
    pub fn parent(&self, index: u64) -> Result<u64, GridError> {
        parent(self.level, index)
    }

    /// The cell containing `rotation` (see [`locate`]).
    pub fn locate(&self, rotation: &UnitQuaternion<f64>) -> Result<u64, GridError> {
        locate(self.level, rotation)
    }

    /// The cell whose centre is nearest to `rotation` in geodesic distance, and that distance
    /// in radians. Exact: a branch-and-bound descent of the HEALPix hierarchy with the exact
    /// best ψ per pixel, so it visits a few dozen pixels, never the whole grid.
    pub fn nearest(&self, rotation: &UnitQuaternion<f64>) -> Result<(u64, f64), GridError> {
        let q = checked_wxyz(rotation)?;
        let index = self.nearest.get_or_init(|| NearestIndex::new(self.level));
        let (pixel, bin, distance) = index.nearest(&q, &self.pixel_bases, &self.half_psi);
        Ok((encode(self.level, pixel, bin), distance))
    }

    fn centre(&self, index: u64) -> [f64; 4] {
        let (pixel, bin) = decode(self.level, index);
        along_fibre(
            &self.pixel_bases[pixel as usize],
            self.half_psi[bin as usize],
        )
    }
}

/// The cell at `level` containing `rotation`, in O(1): the HEALPix pixel of its rotated z-axis
/// and the bin of its ψ (the cells partition SO(3); boundaries go to one side consistently).
pub fn locate(level: u8, rotation: &UnitQuaternion<f64>) -> Result<u64, GridError> {
    check_level(level)?;
    let q = checked_wxyz(rotation)?;
    let axis = rotated_z_axis(&q);
    let (lon, lat) = lon_lat(&axis);
    let pixel = cdshealpix::nested::get(level).hash(lon, lat);
    let base = Section::of_pixel(level, pixel).base(&axis);
    let bins = bin_count(level);
    let bin = ((psi(&base, &q) / TAU * bins as f64) as u64).min(bins - 1);
    Ok(encode(level, pixel, bin))
}

fn checked_wxyz(rotation: &UnitQuaternion<f64>) -> Result<[f64; 4], GridError> {
    let q = rotation.as_ref();
    let wxyz = [q.w, q.i, q.j, q.k];
    if wxyz.iter().any(|v| !v.is_finite()) {
        return Err(GridError::NonFinite { what: "rotation" });
    }
    Ok(wxyz)
}

fn to_unit(q: [f64; 4]) -> UnitQuaternion<f64> {
    let s = if q[0] < 0.0 { -1.0 } else { 1.0 };
    UnitQuaternion::new_unchecked(Quaternion::new(s * q[0], s * q[1], s * q[2], s * q[3]))
}
