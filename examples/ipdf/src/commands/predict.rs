//! `ipdf predict`: the distribution over SO(3) of a trained model for one object in one image
//! (`.npy`, in the cell order of `ipdf grid`), and its most likely rotation (JSON).
use std::path::PathBuf;

use super::check_extension;
use anyhow::Result;
use bop_dataset::write_json;
use ipdf::npy::write_f32;
use ipdf::training_data::{crop_files, crop_tensor};
use ipdf_model::{ArgmaxOptions, ImplicitPdf, Predictor, default_device};
use serde_json::json;
use so3_grid::{Grid, rotation_to_matrix, rotation_to_wxyz};

/// Arguments of `ipdf predict`.
#[derive(Debug, clap::Args)]
pub struct PredictArgs {
    /// Run folder of `ipdf train`.
    #[arg(long)]
    pub checkpoint: PathBuf,
    /// Colour image (PNG or JPEG).
    #[arg(long)]
    pub rgb: PathBuf,
    /// The object's mask in it (non-zero on the object).
    #[arg(long)]
    pub mask: PathBuf,
    /// Grid level of the distribution (4: 294,912 rotations).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(0..=5))]
    pub level: u8,
    /// The distribution: float32 probabilities, one per cell of `ipdf grid --level L`; the
    /// most likely rotation goes beside it as JSON (same name, `.json`).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `ipdf predict`; returns `{"argmax": {"quaternion_wxyz", "cam_R_m2c", "score"}, "level",
/// "cells", "densest": [{"quaternion_wxyz", "probability"}, …]}`.
pub fn run(args: &PredictArgs) -> Result<serde_json::Value> {
    check_extension(
        "--out",
        &args.out,
        "npy",
        "the distribution (a NumPy array; the most likely rotation goes beside it as .json)",
    )?;
    let model = ImplicitPdf::load(&args.checkpoint, default_device())?;
    let size = model.config().input_size as usize;
    let crop = crop_tensor(&crop_files(&args.rgb, &args.mask, size)?, size);
    let mut predictor = Predictor::new(&model);
    let masses = predictor.probabilities(&crop, args.level)?;
    write_f32(&args.out, &[masses.len() as u64], &masses)?;
    let best = predictor.argmax(&crop, &ArgmaxOptions::default())?;
    let grid = Grid::new(args.level)?;
    let mut order: Vec<usize> = (0..masses.len()).collect();
    order.sort_by(|&a, &b| masses[b].total_cmp(&masses[a]));
    let densest = order
        .iter()
        .take(5)
        .map(|&i| {
            let rotation = grid.rotation(i as u64)?;
            Ok(json!({"quaternion_wxyz": rotation_to_wxyz(&rotation), "probability": masses[i]}))
        })
        .collect::<Result<Vec<_>>>()?;
    let result = json!({
        "argmax": {
            "quaternion_wxyz": rotation_to_wxyz(&best.rotation),
            "cam_R_m2c": rotation_to_matrix(&best.rotation),
            "score": best.score,
        },
        "level": args.level,
        "cells": masses.len(),
        "densest": densest,
    });
    write_json(&args.out.with_extension("json"), &result)?;
    Ok(result)
}
