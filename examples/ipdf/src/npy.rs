//! Rotations as NumPy `.npy` arrays, the exchange format with Python (docs/design.md): `N×4`
//! quaternions `w, x, y, z` or `N×3×3` matrices, little-endian float32.
use std::path::Path;

use nalgebra::UnitQuaternion;
use npyz::WriterBuilder;
use so3_grid::{rotation_to_matrix, rotation_to_wxyz};

use bop_dataset::{FileError, write_atomically};

/// How rotations are laid out in a `.npy` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RotationFormat {
    /// `N×4` quaternions `w, x, y, z` with `w ≥ 0`.
    Quat,
    /// `N×3×3` rotation matrices (row-major).
    Matrix,
}

impl RotationFormat {
    /// Every format.
    pub const ALL: [Self; 2] = [Self::Quat, Self::Matrix];

    /// `quat` or `matrix`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Quat => "quat",
            Self::Matrix => "matrix",
        }
    }
}

/// Writes `rotations` to `path` as float32 `.npy` (atomically).
pub fn write_rotations(
    path: &Path,
    rotations: &[UnitQuaternion<f64>],
    format: RotationFormat,
) -> Result<(), FileError> {
    let n = rotations.len() as u64;
    let (shape, values): (Vec<u64>, Vec<f64>) = match format {
        RotationFormat::Quat => (
            vec![n, 4],
            rotations.iter().flat_map(rotation_to_wxyz).collect(),
        ),
        RotationFormat::Matrix => (
            vec![n, 3, 3],
            rotations.iter().flat_map(rotation_to_matrix).collect(),
        ),
    };
    write_f32(path, &shape, &values)
}

/// Writes `values` (row-major, `shape`) to `path` as a float32 `.npy` array (atomically).
pub fn write_f32(path: &Path, shape: &[u64], values: &[f64]) -> Result<(), FileError> {
    write_atomically(path, |out| {
        let mut writer = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(shape)
            .writer(out)
            .begin_nd()?;
        writer.extend(values.iter().map(|&v| v as f32))?;
        writer.finish()
    })
}
