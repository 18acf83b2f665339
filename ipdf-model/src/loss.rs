//! The set negative log-likelihood both models train with: each label in its own normaliser
//! over the step's queries, with importance weights for queries drawn from any proposal; and
//! the check of one image's label set that both models make before it.
use tch::Tensor;

use crate::ModelError;

/// Checks the label set of image `image`, of rotations or translations: a
/// [`ModelError::LabelSet`] for an empty set, or for the first label that is `bad`, with
/// `reason` of its index and value.
pub(crate) fn check_label_set<T>(
    image: usize,
    set: &[T],
    bad: impl Fn(&T) -> bool,
    reason: impl Fn(usize, &T) -> String,
) -> Result<(), ModelError> {
    if set.is_empty() {
        return Err(ModelError::LabelSet {
            image,
            reason: "empty label set".into(),
        });
    }
    match set.iter().position(bad) {
        Some(i) => Err(ModelError::LabelSet {
            image,
            reason: reason(i, &set[i]),
        }),
        None => Ok(()),
    }
}

/// How far below the best query score (in nats) a score stops mattering to the normaliser.
const NEGLIGIBLE_LOG_RATIO: f64 = 50.0;

/// The set negative log-likelihood for queries drawn from any proposal `q` (importance
/// sampling):
/// `ln p(t_bk) = F(t_bk) − ln(e^{F(t_bk) − ln q(t_bk)} + Σ_n e^{F(Q_bn) − ln q(Q_bn)}) + ln N`
/// from `other_terms` `[B, N − 1]` (`F − ln q` at the other queries), `label_scores` `[B, K]`
/// (`F`), `label_terms` `[B, K]` (`F − ln q` at the labels) and `log_offset` (`ln N`). With
/// `q` uniform the `ln q` are constants and move into `log_offset`, as the rotation model's
/// [`crate::rotation::set_nll`] does.
pub(crate) fn set_nll_with(
    other_terms: &Tensor,
    label_scores: &Tensor,
    label_terms: &Tensor,
    label_mask: &Tensor,
    log_offset: f64,
) -> Tensor {
    // Terms more than `NEGLIGIBLE_LOG_RATIO` below the best of the other queries add less
    // than N·e⁻⁵⁰ to their sum: clamping them (with no gradient) changes the loss by under 1e-18
    // and keeps the softmax's backward pass out of subnormal floats, ~100× slower on CPUs.
    let best = other_terms.amax([1], true).detach();
    let log_others = other_terms
        .maximum(&(best - NEGLIGIBLE_LOG_RATIO))
        .logsumexp([1], true); // [B, 1]
    let log_normalisers =
        Tensor::stack(&[&log_others.expand_as(label_terms), label_terms], 2).logsumexp([2], false); // [B, K]
    let log_density = label_scores - log_normalisers + log_offset;
    let per_image =
        (log_density * label_mask).sum_dim_intlist([1].as_slice(), false, label_mask.kind())
            / label_mask.sum_dim_intlist([1].as_slice(), false, label_mask.kind());
    -per_image.mean(label_scores.kind())
}
