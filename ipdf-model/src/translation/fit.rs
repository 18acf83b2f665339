//! Translation training over epochs ([`crate::fit`]): crops with their geometry and translation
//! label sets, validated by the LLH of the labels on the refined octree.
use std::path::Path;

use nalgebra::Vector3;
use tch::Tensor;

use super::model::check_translation_sets;
use super::{CropGeometry, TranslationPdf, TranslationPredictor, TranslationTrainer};
use crate::ModelError;
use crate::StepReport;
use crate::fit::{FitOptions, FitTarget, check_image_stack, select_images};

/// The cell size (mm) the validation LLH refines the octree to.
const VALIDATION_CELL_MM: f64 = 2.0;

/// Crops, where they came from, and their translation label sets (mm).
#[derive(Debug)]
pub struct LabelledTranslations {
    images: Tensor,
    geometry: Vec<CropGeometry>,
    label_sets: Vec<Vec<Vector3<f64>>>,
}

impl LabelledTranslations {
    /// `images`: `[N, 3, S, S]`, float in `[0, 1]` or 8-bit; one [`CropGeometry`] and one
    /// non-empty set of finite translations in front of the camera per crop.
    pub fn new(
        images: Tensor,
        geometry: Vec<CropGeometry>,
        label_sets: Vec<Vec<Vector3<f64>>>,
    ) -> Result<Self, ModelError> {
        let count = check_image_stack(&images)?;
        if count != label_sets.len() {
            return Err(ModelError::LabelSet {
                image: label_sets.len().min(count),
                reason: format!("{} label sets for {count} crops", label_sets.len()),
            });
        }
        check_translation_sets(&label_sets, &geometry)?;
        Ok(Self {
            images,
            geometry,
            label_sets,
        })
    }

    /// The number of crops.
    pub fn len(&self) -> usize {
        self.label_sets.len()
    }

    /// Whether there are no crops (never true: [`LabelledTranslations::new`] refuses that).
    pub fn is_empty(&self) -> bool {
        self.label_sets.is_empty()
    }

    /// The label sets.
    pub fn label_sets(&self) -> &[Vec<Vector3<f64>>] {
        &self.label_sets
    }

    /// The crops' geometry.
    pub fn geometry(&self) -> &[CropGeometry] {
        &self.geometry
    }

    /// The crops at `indices` as floats in `[0, 1]`, with their geometry and label sets.
    pub fn batch(&self, indices: &[usize]) -> (Tensor, Vec<CropGeometry>, Vec<Vec<Vector3<f64>>>) {
        (
            select_images(&self.images, indices),
            indices.iter().map(|&i| self.geometry[i]).collect(),
            indices
                .iter()
                .map(|&i| self.label_sets[i].clone())
                .collect(),
        )
    }
}

/// The mean over crops of the mean over each crop's labels of `ln p(t | I)` (per mm³), the
/// normaliser from the octree of each crop's volume refined to cells of at most 2 mm
/// ([`TranslationPredictor::refine_options`]); `−ln |V|` for a uniform density over that
/// volume `V`.
pub fn translation_validation_llh(
    model: &TranslationPdf,
    data: &LabelledTranslations,
) -> Result<f64, ModelError> {
    let predictor = TranslationPredictor::new(model);
    let mut total = 0.0;
    for image in 0..data.len() {
        let (crop, geometry, sets) = data.batch(&[image]);
        let options = predictor.refine_options(&geometry[0], VALIDATION_CELL_MM);
        let distribution = predictor.hierarchical(&crop, &geometry[0], &options)?;
        let densities = predictor.log_densities(&crop, &geometry[0], &sets[0], &distribution)?;
        total += densities.iter().sum::<f64>() / densities.len() as f64;
    }
    Ok(total / data.len() as f64)
}

impl FitTarget for TranslationTrainer {
    type Data = LabelledTranslations;

    fn examples(data: &LabelledTranslations) -> usize {
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
        data: &LabelledTranslations,
        indices: &[usize],
    ) -> Result<StepReport, ModelError> {
        let (images, geometry, sets) = data.batch(indices);
        self.train_step(&images, &geometry, &sets)
    }

    /// [`translation_validation_llh`] (the grid level of `options` is for rotations).
    fn validation_llh(
        &self,
        data: &LabelledTranslations,
        _options: &FitOptions,
    ) -> Result<f64, ModelError> {
        translation_validation_llh(self.model(), data)
    }

    fn save_to(&self, dir: &Path) -> Result<(), ModelError> {
        self.save(dir)
    }
}
