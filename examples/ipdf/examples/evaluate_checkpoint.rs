//! Evaluate a checkpoint: LLH, MAAD and Recall MAAD of the model saved by `train_steps` on new
//! frames of the cube, against their full symmetry sets (as `ipdf eval` does on a dataset).
//!
//! ```text
//! cargo run --release -p ipdf --example evaluate_checkpoint -- runs/examples/cube
//! ```
use std::path::PathBuf;

use anyhow::Result;
use ipdf::eval::rotation::evaluate;
use ipdf::training_data::rendered_examples;
use ipdf_model::RefineOptions;
use ipdf_model::rotation::ImplicitPdf;
use synth_data::{ObjectKind, SynthObject};

fn main() -> Result<()> {
    let run = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or("runs/examples/cube".into()),
    );
    let model = ImplicitPdf::load(&run, ipdf_model::default_device())?;
    // Frames the model has not seen (another seed), at the checkpoint's crop size.
    let cube = SynthObject::built_in(ObjectKind::Cube)?;
    let size = model.config().input_size as usize;
    let examples = rendered_examples(&cube, 8, size, 99)?;
    // Level 2 refined hierarchically to level 4 (as `ipdf eval` does by default).
    let scores = evaluate(&model, &examples, &RefineOptions::to_level(4), &())?;
    println!(
        "{} images: LLH {:.2} (uniform: −2.29), MAAD {:.1}°, Recall MAAD {:.1}°",
        scores.images, scores.llh, scores.maad_deg, scores.recall_maad_deg
    );
    Ok(())
}
