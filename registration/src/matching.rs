//! Mutual nearest neighbours in FPFH space, by blocked matrix products (faer).
//!
//! A k-d tree does poorly in 33 dimensions: on a 1,600 × 1,000 feature match, kiddo took
//! about 120 ms where the exhaustive search below takes a few milliseconds, because
//! ‖s − t‖² = ‖s‖² + ‖t‖² − 2 s·t turns the search into one GEMM per block of rows.

use faer::{Accum, Mat, Par};
use rayon::prelude::*;

use crate::fpfh::{FPFH_LEN, Fpfh};

/// A squared feature distance and the index it was found at.
type Best = (f32, u32);

/// Source rows per GEMM block.
const BLOCK: usize = 256;

/// Nearest neighbours in feature space (Euclidean) both ways.
pub(crate) struct FeatureMatches {
    /// For each source feature, the index of the nearest target feature.
    pub(crate) to_target: Vec<u32>,
    /// For each target feature, the index of the nearest source feature.
    pub(crate) to_source: Vec<u32>,
}

impl FeatureMatches {
    /// (source, target) pairs that are each other's nearest neighbour, in source order.
    pub(crate) fn mutual(&self) -> Vec<(u32, u32)> {
        self.to_target
            .iter()
            .enumerate()
            .filter(|&(s, &t)| self.to_source[t as usize] == s as u32)
            .map(|(s, &t)| (s as u32, t))
            .collect()
    }

    /// Each target feature with its nearest source feature, in target order.
    pub(crate) fn target_to_source(&self) -> Vec<(u32, u32)> {
        self.to_source
            .iter()
            .enumerate()
            .map(|(t, &s)| (s, t as u32))
            .collect()
    }
}

/// Nearest neighbours both ways between two feature sets; ties go to the lower index, so the
/// result is deterministic.
pub(crate) fn match_features(source: &[Fpfh], target: &[Fpfh]) -> FeatureMatches {
    if source.is_empty() || target.is_empty() {
        return FeatureMatches {
            to_target: Vec::new(),
            to_source: Vec::new(),
        };
    }
    let target_matrix = Mat::<f32>::from_fn(target.len(), FPFH_LEN, |i, j| target[i][j]);
    let target_norms: Vec<f32> = target.iter().map(squared_norm).collect();
    // Per block: each source row's best target, and each target column's best source row.
    let blocks: Vec<(Vec<Best>, Vec<Best>)> = source
        .par_chunks(BLOCK)
        .enumerate()
        .map(|(block, rows)| {
            let first = (block * BLOCK) as u32;
            let source_matrix = Mat::<f32>::from_fn(rows.len(), FPFH_LEN, |i, j| rows[i][j]);
            // Targets × rows, column-major: each source row's products are one contiguous slice.
            let mut products = Mat::<f32>::zeros(target.len(), rows.len());
            faer::linalg::matmul::matmul(
                products.as_mut(),
                Accum::Replace,
                target_matrix.as_ref(),
                source_matrix.transpose(),
                1.0,
                Par::Seq,
            );
            let mut row_best = Vec::with_capacity(rows.len());
            let mut column_distance = vec![f32::INFINITY; target.len()];
            let mut column_index = vec![0u32; target.len()];
            let mut distances = vec![0f32; target.len()];
            for (r, row) in rows.iter().enumerate() {
                // Branch-free passes over contiguous slices, so that they vectorise.
                let row_norm = squared_norm(row);
                for ((d, &norm), &product) in distances
                    .iter_mut()
                    .zip(&target_norms)
                    .zip(products.col_as_slice(r))
                {
                    *d = row_norm + norm - 2.0 * product;
                }
                let smallest = minimum(&distances);
                let nearest = distances.iter().position(|&d| d == smallest).unwrap_or(0);
                row_best.push((smallest, nearest as u32));
                let row_index = first + r as u32;
                for ((best, index), &d) in column_distance
                    .iter_mut()
                    .zip(&mut column_index)
                    .zip(&distances)
                {
                    let closer = d < *best;
                    *index = if closer { row_index } else { *index };
                    *best = if closer { d } else { *best };
                }
            }
            let column_best = column_distance.into_iter().zip(column_index).collect();
            (row_best, column_best)
        })
        .collect();
    let mut column_best = vec![(f32::INFINITY, 0u32); target.len()];
    for (_, columns) in &blocks {
        for (best, candidate) in column_best.iter_mut().zip(columns) {
            // Blocks come in source order, so a strict `<` keeps the lower index on ties.
            if candidate.0 < best.0 {
                *best = *candidate;
            }
        }
    }
    FeatureMatches {
        to_target: blocks
            .iter()
            .flat_map(|(rows, _)| rows)
            .map(|&(_, t)| t)
            .collect(),
        to_source: column_best.iter().map(|&(_, s)| s).collect(),
    }
}

/// The smallest value (eight independent lanes, so the loop vectorises); `INFINITY` if empty.
fn minimum(values: &[f32]) -> f32 {
    let mut lanes = [f32::INFINITY; 8];
    let chunks = values.chunks_exact(8);
    let rest = chunks
        .remainder()
        .iter()
        .fold(f32::INFINITY, |m, &v| m.min(v));
    for chunk in chunks {
        for (lane, &v) in lanes.iter_mut().zip(chunk) {
            *lane = lane.min(v);
        }
    }
    lanes.iter().fold(rest, |m, &v| m.min(v))
}

fn squared_norm(feature: &Fpfh) -> f32 {
    feature.iter().map(|v| v * v).sum()
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    fn nearest(query: &Fpfh, among: &[Fpfh]) -> usize {
        let distance = |f: &Fpfh| {
            f.iter()
                .zip(query)
                .map(|(a, b)| f64::from(a - b).powi(2))
                .sum::<f64>()
        };
        (0..among.len())
            .min_by(|&a, &b| distance(&among[a]).total_cmp(&distance(&among[b])))
            .unwrap()
    }

    #[test]
    fn matches_exhaustive_search_across_blocks() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut random = |n: usize| -> Vec<Fpfh> {
            (0..n)
                .map(|_| std::array::from_fn(|_| rng.random::<f32>() * 100.0))
                .collect()
        };
        let source = random(600);
        let target = random(400);
        let found = match_features(&source, &target).mutual();
        let expected: Vec<(u32, u32)> = (0..source.len())
            .filter_map(|s| {
                let t = nearest(&source[s], &target);
                (nearest(&target[t], &source) == s).then_some((s as u32, t as u32))
            })
            .collect();
        assert!(!expected.is_empty());
        assert_eq!(found, expected);
    }

    #[test]
    fn identical_sets_match_one_to_one() {
        // 300 distinct features: (7i + 13j) mod 97 repeats every 97 features, so each block of
        // 97 is shifted by a quarter in every component. Each feature's unique nearest feature
        // is then itself (distance 0): every feature is a mutual pair with its own index, and
        // nothing else is.
        let features: Vec<Fpfh> = (0..300)
            .map(|i| {
                std::array::from_fn(|j| ((i * 7 + j * 13) % 97) as f32 + (i / 97) as f32 * 0.25)
            })
            .collect();
        let found = match_features(&features, &features).mutual();
        assert_eq!(found, (0..300).map(|i| (i, i)).collect::<Vec<_>>());
        assert!(match_features(&[], &features).mutual().is_empty());
    }
}
