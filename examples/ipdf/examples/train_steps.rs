//! Train a few steps: an Implicit-PDF model of the cube on label sets (its 24 symmetric poses),
//! from crops of rendered frames, saved as a checkpoint that `evaluate_checkpoint` reads.
//!
//! ```text
//! cargo run --release -p ipdf --example train_steps -- runs/examples/cube
//! ```
use std::path::PathBuf;

use anyhow::{Context, Result};
use ipdf::training_data::{rendered_examples, to_unit_floats};
use ipdf_model::ModelConfig;
use ipdf_model::rotation::{ImplicitPdf, QuerySampling, TrainOptions, Trainer};
use synth_data::{ObjectKind, SynthObject};

/// Side of the crops.
const SIZE: usize = 32;

fn main() -> Result<()> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or("runs/examples/cube".into()),
    );
    let cube = SynthObject::built_in(ObjectKind::Cube)?;
    let examples = rendered_examples(&cube, 64, SIZE, 0)?;
    let images = to_unit_floats(&examples.crops);
    let labels = examples.label_sets; // each pose with its 23 symmetric ones
    let model = ImplicitPdf::new(
        ModelConfig::small(SIZE as i64),
        ipdf_model::default_device(),
    )?;
    let options = TrainOptions {
        queries: QuerySampling::Grid { level: 1 },
        ..TrainOptions::default()
    };
    let mut trainer = Trainer::new(model, options)?;
    for step in 0..30 {
        let first = (step * 8) % 64;
        let batch = images.narrow(0, first as i64, 8);
        let report = trainer.train_step(&batch, &labels[first..first + 8])?;
        if step % 10 == 9 {
            println!("step {}: loss {:.3}", step + 1, report.loss);
        }
    }
    trainer.save(&out).context("saving the checkpoint")?;
    println!("checkpoint in {}", out.display());
    Ok(())
}
