//! The early stop's score of each object, from a sample of a scene's instances.
//!
//! A trial scoring under `good_score` ends the search for an instance's first label: on the
//! sensor's noise alone the true pose scores about 0.83. An object whose true poses score
//! higher (the YCB mug scan's score 0.83–0.96 over its views) would search on almost every
//! instance for a better pose that is not there.
//! So [`crate::label_dataset`] labels a sample of each scene's images first
//! ([`split_sample`]: [`SAMPLE_IMAGES`] spread evenly), with the options as given, and
//! raises each object's early stop for the rest of the scene to the upper fence of the
//! sample's best scores ([`upper_fence`]: the largest score that is not an outlier among
//! them), by at most [`MAX_RAISE`]; an object with fewer than [`MIN_INSTANCES`] labelled
//! instances in the sample keeps `good_score`. An object whose true poses score as the
//! sensor's noise leads to expect keeps it too (the fence lies under it), and so do its labels.
use std::collections::BTreeMap;

use crate::LabelOptions;

/// Images per scene labelled before the early stop is set: the first, then every
/// (n/64)-th.
pub(crate) const SAMPLE_IMAGES: usize = 64;

/// Labelled instances of an object in the sample below which its early stop stays
/// `good_score`: too few to tell its spread from a mistaken pose.
pub(crate) const MIN_INSTANCES: usize = 16;

/// The early stop rises at most this far above `good_score`: one near `max_score` would end
/// the search at any accepted pose.
pub(crate) const MAX_RAISE: f64 = 0.05;

/// `ids` split into the sample ([`SAMPLE_IMAGES`] of them spread evenly, the first
/// included; all of them when there are no more) and the rest, both in the order given.
pub(crate) fn split_sample(ids: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let (n, k) = (ids.len(), SAMPLE_IMAGES.min(ids.len()));
    let (mut sample, mut rest) = (Vec::with_capacity(k), Vec::with_capacity(n - k));
    for (position, &id) in ids.iter().enumerate() {
        // The sample's j-th image sits at position ⌊j n / k⌋.
        if sample.len() < k && position == sample.len() * n / k {
            sample.push(id);
        } else {
            rest.push(id);
        }
    }
    (sample, rest)
}

/// Tukey's upper fence of `scores`: the third quartile plus 1.5 times the interquartile
/// range, quartiles interpolated linearly between order statistics; `None` when empty.
pub(crate) fn upper_fence(scores: &[f64]) -> Option<f64> {
    let mut sorted = scores.to_vec();
    sorted.sort_by(f64::total_cmp);
    let last = sorted.len().checked_sub(1)?;
    let quantile = |p: f64| {
        let at = p * last as f64;
        let (below, above) = (at.floor() as usize, at.ceil() as usize);
        sorted[below] + (at - below as f64) * (sorted[above] - sorted[below])
    };
    let (q1, q3) = (quantile(0.25), quantile(0.75));
    Some(q3 + 1.5 * (q3 - q1))
}

/// The early stop of each object of `sample` (object id, best label's score on the sensor's
/// own noise: [`LabelOptions::noise_shift`] taken off), as the module docs set it from
/// `options.good_score`.
pub(crate) fn good_scores(options: &LabelOptions, sample: &[(u32, f64)]) -> BTreeMap<u32, f64> {
    let mut by_object: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
    for &(obj_id, score) in sample {
        if score.is_finite() {
            by_object.entry(obj_id).or_default().push(score);
        }
    }
    by_object
        .into_iter()
        .map(|(obj_id, scores)| {
            let fence = (scores.len() >= MIN_INSTANCES)
                .then(|| upper_fence(&scores))
                .flatten()
                .unwrap_or(options.good_score);
            let good = fence.clamp(options.good_score, options.good_score + MAX_RAISE);
            (obj_id, good)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_sample_is_spread_evenly_and_the_rest_is_the_complement() {
        let ids: Vec<u32> = (0..200).map(|i| 3 * i).collect();
        let (sample, rest) = split_sample(&ids);
        assert_eq!(sample.len(), SAMPLE_IMAGES);
        assert_eq!(rest.len(), 200 - SAMPLE_IMAGES);
        assert_eq!(sample[0], 0);
        // Positions ⌊64 i / 200⌋ · … : gaps of 3 or 4 positions, never more.
        for pair in sample.windows(2) {
            let gap = (pair[1] - pair[0]) / 3;
            assert!((3..=4).contains(&gap), "{pair:?}");
        }
        let mut all: Vec<u32> = sample.iter().chain(&rest).copied().collect();
        all.sort_unstable();
        assert_eq!(all, ids);

        let few: Vec<u32> = (0..10).collect();
        assert_eq!(split_sample(&few), (few.clone(), Vec::new()));
    }

    #[test]
    fn the_fence_of_an_arithmetic_sequence_is_its_closed_form() {
        // 0, 1, …, 100: Q1 = 25, Q3 = 75, fence 75 + 1.5 · 50.
        let scores: Vec<f64> = (0..=100).rev().map(f64::from).collect();
        assert_eq!(upper_fence(&scores), Some(150.0));
        // 1, 2, 3, 4: Q1 = 1.75, Q3 = 3.25 (numpy's default interpolation).
        assert_eq!(upper_fence(&[4.0, 1.0, 3.0, 2.0]), Some(3.25 + 1.5 * 1.5));
        assert_eq!(upper_fence(&[]), None);
    }

    fn options() -> LabelOptions {
        LabelOptions::default()
    }

    #[test]
    fn an_object_scoring_as_the_sensor_leads_to_expect_keeps_the_good_score() {
        let sample: Vec<(u32, f64)> = (0..40).map(|i| (1, 0.80 + 0.001 * f64::from(i))).collect();
        assert_eq!(good_scores(&options(), &sample)[&1], options().good_score);
    }

    #[test]
    fn an_object_scoring_higher_gets_its_fence_up_to_the_cap() {
        // 0.86, 0.8605, …, 0.8995: Q1 = 0.869875, Q3 = 0.889625, fence 0.9192500.
        let wide: Vec<(u32, f64)> = (0..80).map(|i| (2, 0.86 + 0.0005 * f64::from(i))).collect();
        let good = good_scores(&options(), &wide)[&2];
        assert!((good - 0.919_25).abs() < 1e-9, "{good}");
        // Far above: capped.
        let high: Vec<(u32, f64)> = (0..40).map(|i| (3, 1.0 + 0.01 * f64::from(i))).collect();
        assert_eq!(
            good_scores(&options(), &high)[&3],
            options().good_score + MAX_RAISE
        );
    }

    #[test]
    fn too_few_instances_or_unscored_ones_keep_the_good_score() {
        let few: Vec<(u32, f64)> = (0..MIN_INSTANCES - 1).map(|_| (4, 1.1)).collect();
        assert_eq!(good_scores(&options(), &few)[&4], options().good_score);
        let mut unscored: Vec<(u32, f64)> = few.clone();
        unscored.push((4, f64::NAN));
        assert_eq!(good_scores(&options(), &unscored)[&4], options().good_score);
    }

    proptest! {
        /// The fence moves with the scores: shifted by c it shifts by c, scaled by a > 0 it
        /// scales by a, and it never lies under the median.
        #[test]
        fn the_fence_is_equivariant_and_above_the_median(
            scores in prop::collection::vec(-10.0f64..10.0, 1..60),
            c in -5.0f64..5.0,
            a in 0.1f64..10.0,
        ) {
            let fence = upper_fence(&scores).unwrap();
            let shifted: Vec<f64> = scores.iter().map(|s| s + c).collect();
            let scaled: Vec<f64> = scores.iter().map(|s| a * s).collect();
            prop_assert!((upper_fence(&shifted).unwrap() - (fence + c)).abs() < 1e-9);
            prop_assert!((upper_fence(&scaled).unwrap() - a * fence).abs() < 1e-9);
            let mut sorted = scores.clone();
            sorted.sort_by(f64::total_cmp);
            prop_assert!(fence >= sorted[(sorted.len() - 1) / 2] - 1e-12);
        }
    }
}
