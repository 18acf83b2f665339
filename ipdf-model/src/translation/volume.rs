//! The working volume of a translation model and its octree of equal cells.
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::ModelError;
use crate::refine::CellHierarchy;

/// The finest octree level (8¹⁶ cells; a 1 m volume in cells of 15 µm).
pub const MAX_OCTREE_LEVEL: u8 = 16;

/// An axis-aligned box of translations in the camera frame (mm; `z` along the optical axis,
/// in front of the camera): where a translation model's density lives. Its octree has
/// `8^level` equal cells at each level, indexed in Morton order so that the children of cell `i`
/// are `8i..8i + 8` (see [`CellHierarchy`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorkingVolume {
    /// The lowest corner, mm.
    pub min: [f64; 3],
    /// The highest corner, mm.
    pub max: [f64; 3],
}

impl WorkingVolume {
    /// The box from `min` to `max` (mm): finite, `max > min` on every axis, `min.z > 0`.
    pub fn new(min: [f64; 3], max: [f64; 3]) -> Result<Self, ModelError> {
        let volume = Self { min, max };
        volume.validate()?;
        Ok(volume)
    }

    /// The box around `translations` (mm) padded on every side by `margin` times its extent
    /// along that axis and at least `min_padding` mm; `z` stays in front of the camera (at least
    /// 1 mm).
    pub fn around(
        translations: &[Vector3<f64>],
        margin: f64,
        min_padding: f64,
    ) -> Result<Self, ModelError> {
        if translations.is_empty() {
            return Err(ModelError::option(
                "translations",
                "no translation to bound",
            ));
        }
        if !(margin.is_finite() && margin >= 0.0 && min_padding.is_finite() && min_padding >= 0.0) {
            return Err(ModelError::option(
                "margin",
                format!("{margin} and {min_padding} mm: need finite values ≥ 0"),
            ));
        }
        if let Some(i) = translations
            .iter()
            .position(|t| !t.iter().all(|v| v.is_finite()))
        {
            return Err(ModelError::option(
                "translations",
                format!("translation {i} is not finite"),
            ));
        }
        let mut min = [f64::INFINITY; 3];
        let mut max = [f64::NEG_INFINITY; 3];
        for t in translations {
            for axis in 0..3 {
                min[axis] = min[axis].min(t[axis]);
                max[axis] = max[axis].max(t[axis]);
            }
        }
        for axis in 0..3 {
            let padding = (margin * (max[axis] - min[axis]))
                .max(min_padding)
                .max(1e-3);
            min[axis] -= padding;
            max[axis] += padding;
        }
        min[2] = min[2].max(1.0);
        Self::new(min, max)
    }

    /// Checks that the box is finite, not empty, and in front of the camera.
    pub fn validate(&self) -> Result<(), ModelError> {
        let finite = self.min.iter().chain(&self.max).all(|v| v.is_finite());
        let ordered = (0..3).all(|axis| self.max[axis] > self.min[axis]);
        if !finite || !ordered || self.min[2] <= 0.0 {
            return Err(ModelError::option(
                "volume",
                format!(
                    "{:?} to {:?} mm: need finite corners, max > min and z > 0",
                    self.min, self.max
                ),
            ));
        }
        Ok(())
    }

    /// Side lengths, mm.
    pub fn extent(&self) -> Vector3<f64> {
        Vector3::from(self.max) - Vector3::from(self.min)
    }

    /// Whether `t` (mm) lies inside (boundary included).
    pub fn contains(&self, t: &Vector3<f64>) -> bool {
        (0..3).all(|axis| (self.min[axis]..=self.max[axis]).contains(&t[axis]))
    }

    /// The coarsest level whose cells are at most `size` mm along every axis (capped at
    /// [`MAX_OCTREE_LEVEL`]).
    pub fn level_for_cell_size(&self, size: f64) -> u8 {
        let longest = self.extent().max();
        (0..MAX_OCTREE_LEVEL)
            .find(|&level| longest / f64::from(1u32 << level) <= size)
            .unwrap_or(MAX_OCTREE_LEVEL)
    }

    /// The centre (mm) of cell `index` of `level`.
    pub fn cell_centre(&self, level: u8, index: u64) -> Result<Vector3<f64>, ModelError> {
        self.check_cell(level, index)?;
        let side = f64::from(1u32 << level);
        let [x, y, z] = morton_decode(level, index);
        let cells = Vector3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) / side;
        Ok(Vector3::from(self.min) + self.extent().component_mul(&cells))
    }

    /// The cell of `level` holding `t` (mm); an error outside the volume.
    pub fn locate(&self, level: u8, t: &Vector3<f64>) -> Result<u64, ModelError> {
        if level > MAX_OCTREE_LEVEL {
            return Err(ModelError::option(
                "level",
                format!("{level}: octree levels go up to {MAX_OCTREE_LEVEL}"),
            ));
        }
        if !self.contains(t) {
            return Err(ModelError::OutsideVolume {
                translation: [t.x, t.y, t.z],
                min: self.min,
                max: self.max,
            });
        }
        let side = 1u64 << level;
        let mut coordinates = [0u64; 3];
        for axis in 0..3 {
            let fraction = (t[axis] - self.min[axis]) / (self.max[axis] - self.min[axis]);
            coordinates[axis] = ((fraction * side as f64) as u64).min(side - 1);
        }
        Ok(morton_encode(level, coordinates))
    }

    fn check_cell(&self, level: u8, index: u64) -> Result<(), ModelError> {
        if level > MAX_OCTREE_LEVEL || index >= self.cell_count(level) {
            return Err(ModelError::option(
                "cell",
                format!("cell {index} of level {level}: outside the octree"),
            ));
        }
        Ok(())
    }
}

impl CellHierarchy for WorkingVolume {
    fn max_level(&self) -> u8 {
        MAX_OCTREE_LEVEL
    }

    /// Level 6 (262,144 cells).
    fn max_dense_level(&self) -> u8 {
        6
    }

    fn cell_count(&self, level: u8) -> u64 {
        1u64 << (3 * u32::from(level.min(MAX_OCTREE_LEVEL)))
    }

    /// mm³.
    fn cell_volume(&self, level: u8) -> f64 {
        self.extent().product() / self.cell_count(level) as f64
    }

    fn ball_radius(&self, level: u8) -> f64 {
        (3.0 * self.cell_volume(level) / (4.0 * std::f64::consts::PI)).cbrt()
    }

    fn sibling_offsets(&self, level: u8, first: u64) -> Result<[Vector3<f64>; 8], ModelError> {
        let origin = self.cell_centre(level, first)?;
        let mut offsets = [Vector3::zeros(); 8];
        for (k, offset) in offsets.iter_mut().enumerate() {
            *offset = self.cell_centre(level, first + k as u64)? - origin;
        }
        Ok(offsets)
    }
}

/// The Morton index of integer cell coordinates at `level`: bit `b` of `x`, `y`, `z` goes to bit
/// `3b`, `3b + 1`, `3b + 2`, so that a cell's children differ only in the lowest 3 bits.
fn morton_encode(level: u8, [x, y, z]: [u64; 3]) -> u64 {
    (0..u32::from(level)).fold(0, |index, bit| {
        index
            | ((x >> bit) & 1) << (3 * bit)
            | ((y >> bit) & 1) << (3 * bit + 1)
            | ((z >> bit) & 1) << (3 * bit + 2)
    })
}

/// The inverse of [`morton_encode`].
fn morton_decode(level: u8, index: u64) -> [u64; 3] {
    let mut coordinates = [0u64; 3];
    for bit in 0..u32::from(level) {
        for (axis, value) in coordinates.iter_mut().enumerate() {
            *value |= ((index >> (3 * bit + axis as u32)) & 1) << bit;
        }
    }
    coordinates
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn volume() -> WorkingVolume {
        WorkingVolume::new([-300.0, -200.0, 400.0], [300.0, 250.0, 1100.0]).unwrap()
    }

    proptest! {
        #[test]
        fn cells_are_located_at_their_centres_and_children_inside_parents(
            level in 0u8..10, seed in 0u64..u64::MAX,
        ) {
            let volume = volume();
            let index = seed % volume.cell_count(level);
            let centre = volume.cell_centre(level, index).unwrap();
            prop_assert!(volume.contains(&centre));
            prop_assert_eq!(volume.locate(level, &centre).unwrap(), index);
            let half = volume.extent() / f64::from(1u32 << (level + 1));
            for child in index * 8..index * 8 + 8 {
                let c = volume.cell_centre(level + 1, child).unwrap();
                let offset = c - centre;
                prop_assert!((0..3).all(|a| (offset[a].abs() - half[a] / 2.0).abs() < 1e-9));
                prop_assert_eq!(volume.locate(level, &c).unwrap(), index);
            }
        }

        #[test]
        fn morton_codes_round_trip(level in 0u8..17, x in 0u64..65536, y in 0u64..65536, z in 0u64..65536) {
            let side = 1u64 << level;
            let coordinates = [x % side, y % side, z % side];
            prop_assert_eq!(morton_decode(level, morton_encode(level, coordinates)), coordinates);
        }
    }

    #[test]
    fn cell_volumes_add_up_and_levels_reach_the_asked_size() {
        let volume = volume();
        for level in 0..6 {
            let total = volume.cell_volume(level) * volume.cell_count(level) as f64;
            assert!((total - 600.0 * 450.0 * 700.0).abs() < 1e-6);
        }
        let level = volume.level_for_cell_size(2.0);
        assert_eq!(level, 9, "700 mm / 2⁹ = 1.4 mm, / 2⁸ = 2.7 mm");
        assert!(matches!(
            volume.locate(3, &Vector3::new(0.0, 0.0, 1200.0)),
            Err(ModelError::OutsideVolume { .. })
        ));
    }

    #[test]
    fn bounding_boxes_pad_and_refuse_bad_input() {
        let around = WorkingVolume::around(
            &[
                Vector3::new(0.0, 0.0, 500.0),
                Vector3::new(100.0, 50.0, 900.0),
            ],
            0.25,
            20.0,
        )
        .unwrap();
        assert_eq!(around.min, [-25.0, -20.0, 400.0]);
        assert_eq!(around.max, [125.0, 70.0, 1000.0]);
        assert!(WorkingVolume::around(&[], 0.1, 1.0).is_err());
        assert!(WorkingVolume::around(&[Vector3::new(f64::NAN, 0.0, 1.0)], 0.1, 1.0).is_err());
        assert!(WorkingVolume::new([0.0, 0.0, -5.0], [1.0, 1.0, 1.0]).is_err());
        assert!(WorkingVolume::new([0.0, 0.0, 5.0], [1.0, 1.0, 1.0]).is_err());
    }
}
