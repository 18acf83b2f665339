//! The rotation model's training objective: query sets over SO(3) moved onto the labels, and
//! the negative log-likelihood of the label sets under the density the queries normalise
//! (Murphy et al. 2021, eq. 3–4).
use nalgebra::UnitQuaternion;
use rand::Rng;
use serde::{Deserialize, Serialize};
use so3_grid::{Grid, random_rotation};
use tch::{Device, Kind, Tensor};

use crate::ModelError;
use crate::encoding::rotations_to_tensor;
use crate::loss::{check_label_set, set_nll_with};

/// How the query rotations of a training step are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum QuerySampling {
    /// An `so3-grid` grid of this level (level 2: 4,608), rotated by a uniform random rotation
    /// each step (the reference implementation's default).
    Grid {
        /// The grid level.
        level: u8,
    },
    /// This many uniform random rotations, fresh each step.
    Uniform {
        /// The number of queries.
        count: usize,
    },
}

impl QuerySampling {
    /// The number of queries per image.
    pub fn count(&self) -> usize {
        match *self {
            Self::Grid { level } => so3_grid::cell_count(level) as usize,
            Self::Uniform { count } => count,
        }
    }
}

/// How an image's label set enters the loss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LabelLoss {
    /// One label drawn from the set per image per step; its NLL.
    OneOfSet,
    /// Every label of the set is queried; the mean of their NLLs, each label taking the place
    /// of the first of the step's queries in its own normaliser (see [`set_nll`]).
    WholeSet,
}

/// Draws query sets: `[N, 3, 3]` rotations whose first member is then moved onto a label.
pub(crate) enum QuerySampler {
    /// A fixed grid `[N, 3, 3]`, turned by a random rotation per draw.
    Grid(Tensor),
    /// Fresh uniform rotations, this many, on this device.
    Uniform(usize, Device),
}

impl QuerySampler {
    pub(crate) fn new(sampling: QuerySampling, device: Device) -> Result<Self, ModelError> {
        match sampling {
            QuerySampling::Grid { level } => {
                if level > 4 {
                    return Err(ModelError::option(
                        "queries.level",
                        format!("{level}: training grids go up to level 4 (2.4·10⁵ queries)"),
                    ));
                }
                let rotations = Grid::new(level)?.rotations();
                Ok(Self::Grid(
                    rotations_to_tensor(&rotations, device).reshape([-1, 3, 3]),
                ))
            }
            QuerySampling::Uniform { count } => {
                if !(2..=1 << 20).contains(&count) {
                    return Err(ModelError::option(
                        "queries.count",
                        format!("{count}: need 2..=1048576 queries"),
                    ));
                }
                Ok(Self::Uniform(count, device))
            }
        }
    }

    /// One query set `[N, 3, 3]`, uniformly distributed over SO(3) as a set.
    pub(crate) fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Tensor {
        match self {
            Self::Grid(grid) => {
                let turn = rotations_to_tensor(&[random_rotation(rng)], grid.device());
                turn.reshape([3, 3]).matmul(grid)
            }
            Self::Uniform(count, device) => {
                let rotations: Vec<UnitQuaternion<f64>> =
                    (0..*count).map(|_| random_rotation(rng)).collect();
                rotations_to_tensor(&rotations, *device).reshape([-1, 3, 3])
            }
        }
    }
}

/// Per image, the query set `queries` (`[N, 3, 3]`) right-multiplied so that its first member
/// equals that image's label: `queries · (Q₀ᵀ R_b)`, `[B, N, 3, 3]`. Right multiplication keeps
/// the set uniformly spread, so the label sits among equally-spaced alternatives.
pub(crate) fn queries_through(queries: &Tensor, labels: &Tensor) -> Tensor {
    let first = queries.get(0);
    let shift = first.transpose(0, 1).matmul(labels); // [B, 3, 3]
    queries.unsqueeze(0).matmul(&shift.unsqueeze(1))
}

/// The mean negative log-likelihood of labelled rotations (Murphy et al. 2021, eq. 4 with the
/// set extension). Each label `R_bk` is scored as the reference scores its one ground truth:
/// it takes the place of the first query, so that it sits among the other `N − 1`,
/// `−ln p(R_bk | I_b) = −F(R_bk, I_b) + ln(e^{F(R_bk, I_b)} + Σ_{n≥1} e^{F(Q_bn, I_b)}) − ln(N / π²)`,
/// averaged over the valid labels of each image (`label_mask`, 1 or 0), then over images.
/// Every label is in its own normaliser, so no label's density can exceed `N / π²`: a peak at
/// a label the grid misses raises the normaliser with it instead of rewarding over-confidence
/// (as it would if only the first label were among the queries), and the labels of a dense set
/// (a continuous symmetry) do not crowd one another out of it.
///
/// `query_scores`: `[B, N]`, `F` at the step's `N` queries (equivolumetric, so each stands for
/// volume `π² / N`; the first is where the first label goes); `label_scores`: `[B, K]`, `F` at
/// the labels.
pub fn set_nll(query_scores: &Tensor, label_scores: &Tensor, label_mask: &Tensor) -> Tensor {
    let count = query_scores.size()[1];
    let log_volume = (count as f64 / std::f64::consts::PI.powi(2)).ln();
    let others = query_scores.narrow(1, 1, count - 1);
    set_nll_with(&others, label_scores, label_scores, label_mask, log_volume)
}

/// The rotations of a row-major 3×3 matrix list, as a label set for image `image`: rejects an
/// empty set and matrices that are not rotations (see [`so3_grid::rotation_from_matrix`]).
pub fn label_set_from_matrices(
    image: usize,
    matrices: &[[f64; 9]],
) -> Result<Vec<UnitQuaternion<f64>>, ModelError> {
    if matrices.is_empty() {
        return Err(ModelError::LabelSet {
            image,
            reason: "empty label set".into(),
        });
    }
    matrices
        .iter()
        .enumerate()
        .map(|(i, m)| {
            so3_grid::rotation_from_matrix(m).map_err(|e| ModelError::LabelSet {
                image,
                reason: format!("label {i}: {e}"),
            })
        })
        .collect()
}

/// Checks a batch's label sets: one per image, none empty, all finite unit quaternions.
pub(crate) fn check_label_sets(
    label_sets: &[Vec<UnitQuaternion<f64>>],
    batch: usize,
) -> Result<(), ModelError> {
    if label_sets.len() != batch {
        return Err(ModelError::LabelSet {
            image: label_sets.len().min(batch),
            reason: format!("{} label sets for {batch} images", label_sets.len()),
        });
    }
    for (image, set) in label_sets.iter().enumerate() {
        check_label_set(
            image,
            set,
            |q| !q.coords.iter().all(|v| v.is_finite()) || (q.norm() - 1.0).abs() > 1e-6,
            |i, _| format!("label {i} is not a unit quaternion"),
        )?;
    }
    Ok(())
}

/// Labels padded to the largest set: `[B, K, 9]` rotations and their `[B, K]` validity mask.
pub(crate) fn padded_labels(
    label_sets: &[Vec<UnitQuaternion<f64>>],
    device: Device,
    kind: Kind,
) -> (Tensor, Tensor) {
    let longest = label_sets.iter().map(Vec::len).max().unwrap_or(1);
    let mut rotations = Vec::with_capacity(label_sets.len() * longest);
    let mut mask = Vec::with_capacity(label_sets.len() * longest);
    for set in label_sets {
        for k in 0..longest {
            rotations.push(set[k.min(set.len() - 1)]);
            mask.push(if k < set.len() { 1.0f32 } else { 0.0 });
        }
    }
    let batch = label_sets.len() as i64;
    (
        rotations_to_tensor(&rotations, device).reshape([batch, longest as i64, 9]),
        Tensor::from_slice(&mask)
            .reshape([batch, longest as i64])
            .to_device(device)
            .to_kind(kind),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn uniform_scores_give_the_uniform_density() {
        // Equal scores everywhere: p = 1/π² for any label, NLL = ln π².
        let queries = Tensor::zeros([3, 100], (Kind::Double, Device::Cpu));
        let labels = Tensor::zeros([3, 2], (Kind::Double, Device::Cpu));
        let mask = Tensor::ones([3, 2], (Kind::Double, Device::Cpu));
        let nll = f64::try_from(set_nll(&queries, &labels, &mask)).unwrap();
        assert!((nll - std::f64::consts::PI.powi(2).ln()).abs() < 1e-12);
    }

    #[test]
    fn masked_labels_do_not_count() {
        // The first label is the first query (score 1); the second, masked, would score 50.
        let mut scores = [0.0f64; 10];
        scores[0] = 1.0;
        let queries = Tensor::from_slice(&scores).reshape([1, 10]);
        let labels = Tensor::from_slice(&[1.0f64, 50.0]).reshape([1, 2]);
        let one = Tensor::from_slice(&[1.0f64, 0.0]).reshape([1, 2]);
        let nll = f64::try_from(set_nll(&queries, &labels, &one)).unwrap();
        let expected =
            -(1.0 - (1f64.exp() + 9.0).ln() + (10.0 / std::f64::consts::PI.powi(2)).ln());
        assert!((nll - expected).abs() < 1e-12);
    }

    #[test]
    fn every_label_is_in_its_own_normaliser() {
        // A label far above every query (a peak between grid points) raises its own
        // normaliser with it: its density tends to N/π², never beyond, so the loss stays above
        // −ln(N/π²) however sharp the peak; the other label keeps its uniform density.
        let queries = Tensor::zeros([1, 10], (Kind::Double, Device::Cpu));
        let mask = Tensor::ones([1, 2], (Kind::Double, Device::Cpu));
        let log_volume = (10.0 / std::f64::consts::PI.powi(2)).ln();
        for peak in [10.0, 100.0, 1e4] {
            let labels = Tensor::from_slice(&[0.0f64, peak]).reshape([1, 2]);
            let nll = f64::try_from(set_nll(&queries, &labels, &mask)).unwrap();
            let uniform = -std::f64::consts::PI.powi(2).ln();
            let peaked = -(1.0 + 9.0 * (-peak).exp()).ln() + log_volume;
            let expected = -0.5 * (uniform + peaked);
            assert!((nll - expected).abs() < 1e-12, "{nll} {expected}");
            assert!(nll > -log_volume);
        }
    }

    #[test]
    fn shifted_queries_start_at_the_label_and_stay_rotations() {
        let sampler = QuerySampler::new(QuerySampling::Grid { level: 0 }, Device::Cpu).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let queries = sampler.sample(&mut rng);
        let label = UnitQuaternion::from_euler_angles(0.4, 1.0, -2.0);
        let labels = rotations_to_tensor(&[label], Device::Cpu).reshape([1, 3, 3]);
        let shifted = queries_through(&queries, &labels);
        assert_eq!(shifted.size(), [1, 72, 3, 3]);
        let first = shifted.get(0).get(0);
        assert!(f64::try_from((&first - labels.get(0)).abs().max()).unwrap() < 1e-5);
        let gram =
            shifted.matmul(&shifted.transpose(2, 3)) - Tensor::eye(3, (Kind::Float, Device::Cpu));
        assert!(f64::try_from(gram.abs().max()).unwrap() < 1e-5);
    }

    #[test]
    fn label_sets_reject_non_rotations() {
        let scaled = [2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let err = label_set_from_matrices(4, &[scaled]).unwrap_err();
        assert!(
            matches!(err, ModelError::LabelSet { image: 4, .. }),
            "{err}"
        );
        assert!(label_set_from_matrices(0, &[]).is_err());
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(label_set_from_matrices(0, &[identity]).unwrap().len(), 1);
    }
}
