//! Adam with a state that can be saved and restored, global-norm gradient clipping, and the
//! learning-rate schedule (linear warm-up, then cosine decay).
use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use tch::{Kind, Tensor, nn};

/// Learning rate per step: linear warm-up from `peak / warmup_steps` to `peak` over
/// `warmup_steps`, then cosine decay to 0 at `total_steps`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LearningRateSchedule {
    /// The learning rate at the end of warm-up.
    pub peak: f64,
    /// Steps of linear warm-up.
    pub warmup_steps: u64,
    /// Steps of the whole run (warm-up included).
    pub total_steps: u64,
}

impl LearningRateSchedule {
    /// The learning rate of `step` (0-based); 0 from `total_steps` on.
    pub fn at(&self, step: u64) -> f64 {
        if step < self.warmup_steps {
            return self.peak * (step + 1) as f64 / self.warmup_steps as f64;
        }
        if step >= self.total_steps {
            return 0.0;
        }
        let decay_steps = (self.total_steps - self.warmup_steps).max(1) as f64;
        let progress = (step - self.warmup_steps) as f64 / decay_steps;
        0.5 * self.peak * (1.0 + (std::f64::consts::PI * progress).cos())
    }
}

/// Adam (Kingma & Ba 2015) over the trainable variables of a var store, in name order.
pub(crate) struct Adam {
    names: Vec<String>,
    params: Vec<Tensor>,
    first_moments: Vec<Tensor>,
    second_moments: Vec<Tensor>,
}

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPSILON: f64 = 1e-8;

impl Adam {
    pub(crate) fn new(var_store: &nn::VarStore) -> Self {
        let mut named: Vec<(String, Tensor)> = var_store
            .variables()
            .into_iter()
            .filter(|(_, tensor)| tensor.requires_grad())
            .collect();
        named.sort_by(|a, b| a.0.cmp(&b.0));
        let first_moments = named.iter().map(|(_, p)| p.zeros_like()).collect();
        let second_moments = named.iter().map(|(_, p)| p.zeros_like()).collect();
        let (names, params) = named.into_iter().unzip();
        Self {
            names,
            params,
            first_moments,
            second_moments,
        }
    }

    pub(crate) fn zero_grad(&mut self) {
        for param in &mut self.params {
            param.zero_grad();
        }
    }

    /// Scales the gradients so that their global L2 norm is at most `max_norm`; returns the norm
    /// before scaling.
    pub(crate) fn clip_grad_norm(&mut self, max_norm: f64) -> f64 {
        tch::no_grad(|| {
            let squares: Vec<Tensor> = self
                .params
                .iter()
                .map(|p| p.grad())
                .filter(Tensor::defined)
                .map(|g| g.square().sum(Kind::Double))
                .collect();
            if squares.is_empty() {
                return 0.0;
            }
            let norm = f64::try_from(Tensor::stack(&squares, 0).sum(Kind::Double).sqrt())
                .unwrap_or(f64::NAN);
            if norm.is_finite() && norm > max_norm {
                let scale = max_norm / (norm + 1e-6);
                for param in &self.params {
                    let mut grad = param.grad();
                    if grad.defined() {
                        let _ = grad.g_mul_scalar_(scale);
                    }
                }
            }
            norm
        })
    }

    /// One update with learning rate `learning_rate`; `step` counts updates from 1 (bias
    /// correction).
    pub(crate) fn step(&mut self, learning_rate: f64, step: u64) {
        let correction1 = 1.0 - BETA1.powi(step as i32);
        let correction2 = 1.0 - BETA2.powi(step as i32);
        tch::no_grad(|| {
            for ((param, m), v) in self
                .params
                .iter_mut()
                .zip(&mut self.first_moments)
                .zip(&mut self.second_moments)
            {
                let grad = param.grad();
                if !grad.defined() {
                    continue;
                }
                // In place, two temporaries per tensor: m ← β₁m + (1−β₁)g, v ← β₂v + (1−β₂)g²,
                // θ ← θ − lr/c₁ · m / (√(v/c₂) + ε).
                let _ = m.lerp_(&grad, 1.0 - BETA1);
                let _ = v.lerp_(&grad.square(), 1.0 - BETA2);
                if learning_rate == 0.0 {
                    continue;
                }
                let mut denominator = v.sqrt();
                let _ = denominator
                    .g_div_scalar_(correction2.sqrt())
                    .g_add_scalar_(EPSILON)
                    .g_mul_scalar_(-correction1 / learning_rate);
                let _ = param.addcdiv_(m, &denominator);
            }
        });
    }

    /// The moments as named tensors (`adam.m.<param>`, `adam.v.<param>`).
    pub(crate) fn state(&self) -> Vec<(String, Tensor)> {
        let mut out = Vec::with_capacity(2 * self.names.len());
        for ((name, m), v) in self
            .names
            .iter()
            .zip(&self.first_moments)
            .zip(&self.second_moments)
        {
            out.push((format!("adam.m.{name}"), m.shallow_clone()));
            out.push((format!("adam.v.{name}"), v.shallow_clone()));
        }
        out
    }

    /// Restores the moments saved by [`Adam::state`]; returns the name of the first tensor that
    /// is missing or has another shape.
    pub(crate) fn load_state(&mut self, mut saved: HashMap<String, Tensor>) -> Result<(), String> {
        for ((name, m), v) in self
            .names
            .iter()
            .zip(&mut self.first_moments)
            .zip(&mut self.second_moments)
        {
            for (prefix, target) in [("adam.m.", &mut *m), ("adam.v.", &mut *v)] {
                let key = format!("{prefix}{name}");
                let tensor = saved
                    .remove(&key)
                    .ok_or_else(|| format!("{key}: missing"))?;
                if tensor.size() != target.size() {
                    return Err(format!(
                        "{key}: shape {:?}, expected {:?}",
                        tensor.size(),
                        target.size()
                    ));
                }
                tch::no_grad(|| target.copy_(&tensor));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_warms_up_then_decays_to_zero() {
        let schedule = LearningRateSchedule {
            peak: 1e-3,
            warmup_steps: 10,
            total_steps: 110,
        };
        assert!((schedule.at(0) - 1e-4).abs() < 1e-12);
        assert!((schedule.at(9) - 1e-3).abs() < 1e-12);
        assert!((schedule.at(60) - 5e-4).abs() < 1e-9);
        assert!(schedule.at(109) < 1e-6);
        assert_eq!(schedule.at(500), 0.0);
        for step in 10..109 {
            assert!(schedule.at(step + 1) <= schedule.at(step));
        }
    }

    #[test]
    fn adam_minimises_a_quadratic() {
        let var_store = nn::VarStore::new(tch::Device::Cpu);
        let x = var_store
            .root()
            .var_copy("x", &Tensor::from_slice(&[3.0f32, -2.0]));
        let mut adam = Adam::new(&var_store);
        for step in 1..=500 {
            adam.zero_grad();
            (&x - 1.0).square().sum(Kind::Float).backward();
            adam.step(0.05, step);
        }
        let values = Vec::<f32>::try_from(&x).unwrap();
        assert!(values.iter().all(|v| (v - 1.0).abs() < 1e-2), "{values:?}");
    }
}
