//! Rotation training data: crops with their rotation label sets, validated by the LLH of the
//! labels on a dense SO(3) grid.
use std::path::Path;

use nalgebra::UnitQuaternion;
use so3_grid::locate;
use tch::Tensor;

use super::loss::check_label_sets;
use super::{ImplicitPdf, Predictor, Trainer};
use crate::fit::{FitOptions, FitTarget, check_image_stack, select_images};
use crate::{ModelError, StepReport};

impl FitTarget for Trainer {
    type Data = LabelledImages;

    fn examples(data: &LabelledImages) -> usize {
        data.len()
    }

    fn steps_done(&self) -> u64 {
        self.step()
    }

    fn seed(&self) -> u64 {
        self.options().seed
    }

    fn train_batch(
        &mut self,
        data: &LabelledImages,
        indices: &[usize],
    ) -> Result<StepReport, ModelError> {
        let (images, sets) = data.batch(indices);
        self.train_step(&images, &sets)
    }

    /// On the dense `options.validation_level` grid.
    fn validation_llh(
        &self,
        data: &LabelledImages,
        options: &FitOptions,
    ) -> Result<f64, ModelError> {
        validation_llh(self.model(), data, options.validation_level)
    }

    fn save_to(&self, dir: &Path) -> Result<(), ModelError> {
        self.save(dir)
    }
}

/// Crops and their label sets.
#[derive(Debug)]
pub struct LabelledImages {
    images: Tensor,
    label_sets: Vec<Vec<UnitQuaternion<f64>>>,
}

impl LabelledImages {
    /// `images`: `[N, 3, S, S]`, float in `[0, 1]` or 8-bit (`Kind::Uint8`, 0–255, a quarter of
    /// the memory); one non-empty label set per image.
    pub fn new(
        images: Tensor,
        label_sets: Vec<Vec<UnitQuaternion<f64>>>,
    ) -> Result<Self, ModelError> {
        let count = check_image_stack(&images)?;
        check_label_sets(&label_sets, count)?;
        Ok(Self { images, label_sets })
    }

    /// The number of images.
    pub fn len(&self) -> usize {
        self.label_sets.len()
    }

    /// Whether there are no images (never true: [`LabelledImages::new`] refuses that).
    pub fn is_empty(&self) -> bool {
        self.label_sets.is_empty()
    }

    /// The label sets.
    pub fn label_sets(&self) -> &[Vec<UnitQuaternion<f64>>] {
        &self.label_sets
    }

    /// The images at `indices` as floats in `[0, 1]`, with their label sets.
    pub fn batch(&self, indices: &[usize]) -> (Tensor, Vec<Vec<UnitQuaternion<f64>>>) {
        let sets = indices
            .iter()
            .map(|&i| self.label_sets[i].clone())
            .collect();
        (select_images(&self.images, indices), sets)
    }
}

/// The mean over images of the mean over each image's label set of `ln p(R | I)` on the dense
/// `level` grid (the LLH of Murphy et al. 2021 on that grid; `−ln π² ≈ −2.29` for a uniform
/// density).
pub fn validation_llh(
    model: &ImplicitPdf,
    data: &LabelledImages,
    level: u8,
) -> Result<f64, ModelError> {
    let mut predictor = Predictor::new(model);
    let cells = so3_grid::cell_count(level) as f64;
    let log_volume = (cells / std::f64::consts::PI.powi(2)).ln();
    let mut total = 0.0;
    for image in 0..data.len() {
        let (crop, sets) = data.batch(&[image]);
        let masses = predictor.probabilities(&crop, level)?;
        let set = &sets[0];
        let mut sum = 0.0;
        for rotation in set {
            sum += masses[locate(level, rotation)? as usize].ln() + log_volume;
        }
        total += sum / set.len() as f64;
    }
    Ok(total / data.len() as f64)
}
