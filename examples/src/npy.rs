//! Rotations as NumPy `.npy` arrays, the exchange format with Python (DESIGN.md): `N×4`
//! quaternions `w, x, y, z` or `N×3×3` matrices, little-endian float32.
use std::path::Path;

use anyhow::Result;
use nalgebra::UnitQuaternion;
use npyz::WriterBuilder;
use so3_grid::{rotation_to_matrix, rotation_to_wxyz};

use crate::atomic::write_atomically;

/// How rotations are laid out in a `.npy` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RotationFormat {
    /// `N×4` quaternions `w, x, y, z` with `w ≥ 0`.
    Quat,
    /// `N×3×3` rotation matrices (row-major).
    Matrix,
}

/// Writes `rotations` to `path` as float32 `.npy` (atomically).
pub fn write_rotations(
    path: &Path,
    rotations: &[UnitQuaternion<f64>],
    format: RotationFormat,
) -> Result<()> {
    let n = rotations.len() as u64;
    let shape = match format {
        RotationFormat::Quat => vec![n, 4],
        RotationFormat::Matrix => vec![n, 3, 3],
    };
    write_atomically(path, |out| {
        let mut writer = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&shape)
            .writer(out)
            .begin_nd()?;
        for q in rotations {
            match format {
                RotationFormat::Quat => writer.extend(rotation_to_wxyz(q).map(|v| v as f32))?,
                RotationFormat::Matrix => writer.extend(rotation_to_matrix(q).map(|v| v as f32))?,
            }
        }
        writer.finish()?;
        Ok(())
    })
}
