//! `ipdf grid`: write an equivolumetric SO(3) grid as `.npy` and summarise it.
use super::check_extension;
use super::choice::choice;
use std::path::PathBuf;

use anyhow::Result;
use ipdf::npy::{RotationFormat, write_rotations};
use serde_json::json;
use so3_grid::Grid;

/// Arguments of `ipdf grid`.
#[derive(Debug, clap::Args)]
pub struct GridArgs {
    /// Grid level: 72·8^level rotations (2: 4,608; 4: 294,912; 5: 2,359,296).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=i64::from(so3_grid::MAX_LEVEL)))]
    pub level: u8,
    /// Write the rotations to this `.npy` file (float32); other extensions are refused.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Layout of the `.npy`: N×4 quaternions (w, x, y, z) or N×3×3 matrices.
    #[arg(long, value_parser = choice::<RotationFormat>(), default_value = "quat")]
    pub format: RotationFormat,
}

/// Runs `ipdf grid`; returns the JSON summary `{"level", "count", "cell_volume"}`.
pub fn run(args: &GridArgs) -> Result<serde_json::Value> {
    if let Some(out) = &args.out {
        check_extension(
            "--out",
            out,
            "npy",
            "the grid (a NumPy array; the JSON summary goes to standard output)",
        )?;
    }
    let grid = Grid::new(args.level)?;
    if let Some(out) = &args.out {
        write_rotations(out, &grid.rotations(), args.format)?;
    }
    Ok(json!({"level": args.level, "count": grid.len(), "cell_volume": grid.cell_volume()}))
}
