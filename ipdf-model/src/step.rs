//! One optimisation step, shared by the rotation and translation trainers: what it reports,
//! the update (backward pass, clipping, Adam) and the checks of the options it uses.
use tch::Tensor;

use crate::ModelError;
use crate::augment::Augmentation;
use crate::optim::{Adam, LearningRateSchedule};

/// What one step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    /// Steps done so far, this one included.
    pub step: u64,
    /// The batch's mean negative log-likelihood (nats; `ln π² ≈ 2.29` for a uniform density).
    pub loss: f64,
    /// The learning rate used.
    pub learning_rate: f64,
    /// The gradient's global L2 norm before clipping.
    pub gradient_norm: f64,
}

/// Checks a learning-rate schedule, a clipping norm and augmentation ranges.
pub(crate) fn validate_optimisation(
    s: &LearningRateSchedule,
    clip_norm: f64,
    a: &Augmentation,
) -> Result<(), ModelError> {
    if !(s.peak.is_finite() && s.peak > 0.0) {
        return Err(ModelError::option(
            "schedule.peak",
            format!("{}: need > 0", s.peak),
        ));
    }
    if s.total_steps == 0 || s.warmup_steps > s.total_steps {
        return Err(ModelError::option(
            "schedule.total_steps",
            format!(
                "{} total with {} warm-up steps",
                s.total_steps, s.warmup_steps
            ),
        ));
    }
    if !(clip_norm.is_finite() && clip_norm > 0.0) {
        return Err(ModelError::option(
            "clip_norm",
            format!("{clip_norm}: need > 0"),
        ));
    }
    let [smallest, largest] = a.occlusion_area;
    let areas_ok = (0.0..=1.0).contains(&smallest) && (smallest..=1.0).contains(&largest);
    if !(0.0..=1.0).contains(&a.occlusion_probability)
        || !(0.0..=0.5).contains(&a.colour_jitter)
        || !areas_ok
        || !(0.0..=1.0).contains(&a.blur_probability)
        || !(0.0..=10.0).contains(&a.blur_sigma)
    {
        return Err(ModelError::option(
            "augmentation",
            format!(
                "{a:?}: probabilities and areas need [0, 1], jitter [0, 0.5], blur σ [0, 10] px"
            ),
        ));
    }
    Ok(())
}

/// The update after a step's loss: backward pass, gradient clipping at `clip_norm`, Adam with
/// the scheduled learning rate; `step` counts it. A non-finite loss is refused before anything
/// changes.
pub(crate) fn optimisation_step(
    adam: &mut Adam,
    schedule: &LearningRateSchedule,
    clip_norm: f64,
    step: &mut u64,
    loss: &Tensor,
) -> Result<StepReport, ModelError> {
    let loss_value = f64::try_from(loss)?;
    if !loss_value.is_finite() {
        return Err(ModelError::NonFiniteLoss { step: *step });
    }
    loss.backward();
    let gradient_norm = adam.clip_grad_norm(clip_norm);
    let learning_rate = schedule.at(*step);
    *step += 1;
    adam.step(learning_rate, *step);
    Ok(StepReport {
        step: *step,
        loss: loss_value,
        learning_rate,
        gradient_norm,
    })
}
