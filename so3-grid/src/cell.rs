//! The hierarchical cell numbering shared by every level.
//!
//! A cell is a HEALPix (nested) pixel at depth `L` (`12·4^L` of them) times a bin of ψ
//! (`6·2^L` of them). Level 0 numbers its 72 cells `6·pixel + bin`; each finer level appends one
//! base-8 digit `d = 2·j + b` for the HEALPix child `j ∈ 0..4` and the ψ half `b ∈ 0..2`. So the
//! children of cell `i` are exactly `8i..8i+8` and its parent is `i / 8`.
use std::ops::Range;

use crate::GridError;

/// The finest level this crate builds (`72·8⁸ ≈ 1.2·10⁹` cells; tables for nearest-cell queries
/// stay under 100 MB).
pub const MAX_LEVEL: u8 = 8;

/// Number of cells (grid rotations) at `level`: `72·8^level`.
pub const fn cell_count(level: u8) -> u64 {
    72 << (3 * level as u32)
}

/// Volume of one cell at `level` under the Haar measure normalised to a total volume of π²,
/// the convention of Implicit-PDF: `π² / cell_count(level)`. A uniform density is `1/π²`.
pub fn cell_volume(level: u8) -> f64 {
    std::f64::consts::PI.powi(2) / cell_count(level) as f64
}

/// Number of HEALPix pixels at `level` (nside = 2^level).
pub(crate) const fn pixel_count(level: u8) -> u64 {
    12 << (2 * level as u32)
}

/// Number of ψ bins at `level`.
pub(crate) const fn bin_count(level: u8) -> u64 {
    6 << level as u32
}

pub(crate) fn check_level(level: u8) -> Result<(), GridError> {
    if level > MAX_LEVEL {
        return Err(GridError::LevelOutOfRange {
            level,
            max: MAX_LEVEL,
        });
    }
    Ok(())
}

pub(crate) fn check_cell(level: u8, index: u64) -> Result<(), GridError> {
    check_level(level)?;
    let count = cell_count(level);
    if index >= count {
        return Err(GridError::CellOutOfRange {
            level,
            index,
            count,
        });
    }
    Ok(())
}

/// The cell of HEALPix `pixel` and ψ `bin` at `level` (both in range).
pub(crate) fn encode(level: u8, pixel: u64, bin: u64) -> u64 {
    let level = u32::from(level);
    let mut index = (pixel >> (2 * level)) * 6 + (bin >> level);
    for digit in (0..level).rev() {
        let child = (pixel >> (2 * digit)) & 3;
        let half = (bin >> digit) & 1;
        index = (index << 3) | (child << 1) | half;
    }
    index
}

/// `(pixel, bin)` of cell `index` at `level` (the inverse of [`encode`]).
pub(crate) fn decode(level: u8, index: u64) -> (u64, u64) {
    let level = u32::from(level);
    let top = index >> (3 * level);
    let (mut pixel, mut bin) = (top / 6, top % 6);
    for digit in (0..level).rev() {
        let d = (index >> (3 * digit)) & 7;
        pixel = (pixel << 2) | (d >> 1);
        bin = (bin << 1) | (d & 1);
    }
    (pixel, bin)
}

/// The cell at `level` made of HEALPix (nested) `pixel` (`< 12·4^level`) and ψ `bin`
/// (`< 6·2^level`, bin `k` covers `[k, k+1)·2π/(6·2^level)`).
pub fn cell_index(level: u8, pixel: u64, bin: u64) -> Result<u64, GridError> {
    check_level(level)?;
    if pixel >= pixel_count(level) || bin >= bin_count(level) {
        return Err(GridError::PartOutOfRange { level, pixel, bin });
    }
    Ok(encode(level, pixel, bin))
}

/// `(pixel, bin)` of cell `index` at `level`: its HEALPix (nested) pixel of the rotated z-axis
/// and its ψ bin (the inverse of [`cell_index`]). Summing a distribution over the bins of each
/// pixel gives the distribution of the rotated z-axis on the sphere.
pub fn cell_parts(level: u8, index: u64) -> Result<(u64, u64), GridError> {
    check_cell(level, index)?;
    Ok(decode(level, index))
}

/// The 8 children at `level + 1` of cell `index` at `level`.
pub fn children(level: u8, index: u64) -> Result<Range<u64>, GridError> {
    check_cell(level, index)?;
    check_level(level + 1)?;
    Ok(index * 8..index * 8 + 8)
}

/// The parent at `level − 1` of cell `index` at `level` (`level ≥ 1`).
pub fn parent(level: u8, index: u64) -> Result<u64, GridError> {
    check_cell(level, index)?;
    if level == 0 {
        return Err(GridError::LevelOutOfRange {
            level: 0,
            max: MAX_LEVEL,
        });
    }
    Ok(index / 8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn encode_inverts_decode(level in 0u8..=MAX_LEVEL, seed in any::<u64>()) {
            let index = seed % cell_count(level);
            let (pixel, bin) = decode(level, index);
            prop_assert!(pixel < pixel_count(level) && bin < bin_count(level));
            prop_assert_eq!(encode(level, pixel, bin), index);
        }

        #[test]
        fn children_nest_pixels_and_bins(level in 0u8..MAX_LEVEL, seed in any::<u64>()) {
            let index = seed % cell_count(level);
            let (pixel, bin) = decode(level, index);
            for child in children(level, index).unwrap() {
                let (child_pixel, child_bin) = decode(level + 1, child);
                prop_assert_eq!(child_pixel >> 2, pixel);
                prop_assert_eq!(child_bin >> 1, bin);
                prop_assert_eq!(parent(level + 1, child).unwrap(), index);
            }
        }
    }

    #[test]
    fn counts_follow_the_hopf_product() {
        for level in 0..=MAX_LEVEL {
            assert_eq!(cell_count(level), pixel_count(level) * bin_count(level));
        }
        assert_eq!(cell_count(2), 4_608);
        assert_eq!(cell_count(4), 294_912);
        assert_eq!(cell_count(5), 2_359_296);
    }

    #[test]
    fn out_of_range_is_an_error() {
        assert!(matches!(
            children(MAX_LEVEL, 0),
            Err(GridError::LevelOutOfRange { .. })
        ));
        assert!(matches!(
            parent(0, 3),
            Err(GridError::LevelOutOfRange { .. })
        ));
        assert!(matches!(
            parent(1, 576),
            Err(GridError::CellOutOfRange { count: 576, .. })
        ));
    }
}
