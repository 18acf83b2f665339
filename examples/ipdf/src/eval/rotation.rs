//! The paper's scores of a rotation model on examples with ground truth: for each crop, the
//! normalised distribution on the grid (refined hierarchically, or dense), then LLH (mean
//! log-density over the ground-truth symmetry set), MAAD (expected distance of a sample to the
//! nearest ground-truth rotation) and Recall MAAD (mean distance of each ground-truth rotation
//! to the nearest predicted one), averaged over crops.
use bop_dataset::{Intrinsics, Progress};
use ipdf_metrics::{Distribution, GridCell, RECALL_THRESHOLD, maad, recall_maad};
use ipdf_model::rotation::{ArgmaxOptions, ImplicitPdf, Precision, Predictor};
use ipdf_model::{CellMasses, RefineOptions};
use nalgebra::UnitQuaternion;
use so3_grid::Grid;

use crate::Error;
use crate::plots::plot_distribution;
use crate::training_data::{Examples, FileCrop, crop_tensor, from_camera, to_unit_floats};

/// Mean scores over the crops evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// Crops evaluated.
    pub images: usize,
    /// Mean log-likelihood of the ground-truth set (−2.29 for a uniform density).
    pub llh: f64,
    /// Mean absolute angular deviation, degrees.
    pub maad_deg: f64,
    /// Recall mean absolute angular deviation, degrees.
    pub recall_maad_deg: f64,
    /// The most network queries one crop took.
    pub queries_per_image: usize,
    /// How far the grid is from resolving the model's peaks
    /// ([`Predictor::under_resolution`]), the mean over crops.
    pub under_resolution: f64,
}

/// Scores `model` on every crop of `examples`, its distribution evaluated on the cells
/// `grid` describes ([`RefineOptions::to_level`] for the hierarchical evaluation,
/// [`RefineOptions::dense`] for every cell of a level); `progress` advances by one per crop.
/// LLH is the reference implementation's: the density `exp(F(R) − ln Z)` at each ground-truth
/// rotation itself, `Z` from the grid; MAAD and Recall MAAD come from the `metrics` crate on
/// the cells' masses. Fails when the examples have no ground truth.
pub fn evaluate(
    model: &ImplicitPdf,
    examples: &Examples,
    grid: &RefineOptions,
    progress: &dyn Progress,
) -> Result<Scores, Error> {
    let models = std::slice::from_ref(model);
    Ok(evaluate_rotations(models, examples, grid, 0, Picks::default(), progress)?.scores)
}

/// Each crop's scores beside the means: what [`evaluate_rotations`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct RotationEvaluation {
    /// The means over the crops.
    pub scores: Scores,
    /// Each crop's LLH (mean log-density over its ground-truth set).
    pub llh: Vec<f64>,
    /// Each crop's MAAD, degrees.
    pub maad_deg: Vec<f64>,
    /// Each crop's Recall MAAD, degrees.
    pub recall_maad_deg: Vec<f64>,
    /// Each crop's rotation estimate ([`Picks::ball`]), in the camera's frame (empty unless
    /// asked for).
    pub estimates: Vec<UnitQuaternion<f64>>,
    /// Each crop's rotation hypotheses, its estimate first, in the camera's frame (empty
    /// unless asked for; [`ipdf_model::CellMasses::rotation_hypotheses`]).
    pub hypotheses: Vec<Vec<UnitQuaternion<f64>>>,
}

/// The cells [`Picks::ball`] centres its ball on: the densest 512, about two 15° balls of
/// level-4 cells (one holds about 280). On the real YCB-Video objects' models every cell as a
/// candidate picked the same rotations (docs/experiments.md, "The heaviest ball").
pub const BALL_CANDIDATES: usize = 512;

/// Which rotations [`evaluate_rotations`] picks from each crop's distribution beside its scores.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Picks {
    /// The rotation estimate: the most likely rotation, or with [`Picks::ball`] the centre of
    /// the heaviest ball.
    pub estimates: bool,
    /// In place of the most likely rotation, the centre of the ball of this radius (radians)
    /// holding the most probability ([`CellMasses::heaviest_ball`], among the
    /// [`BALL_CANDIDATES`] densest cells).
    pub ball: Option<f64>,
    /// This many rotation hypotheses (0: none; they start at the estimate)…
    pub hypotheses: usize,
    /// …at least this far apart (radians).
    pub hypothesis_spacing: f64,
}

/// [`evaluate`], with each crop's LLH, MAAD and Recall MAAD, and the rotations `picks` asks
/// for: each crop's rotation estimate (its most likely rotation, [`Predictor::argmax_from`] on
/// the same distribution, or its heaviest ball's centre), its rotation hypotheses (starting at
/// the estimate). `models` are one model or the members of an ensemble
/// ([`Predictor::ensemble`], [`ImplicitPdf::load_ensemble`]). Each crop's image term is
/// computed once, averaged over the crop and `views` test-time views of it
/// ([`Predictor::with_views`]). A model in the line of sight's frame is scored against the
/// truth turned into it, crop by crop, and its rotations are turned back into the camera's
/// ([`Examples::frame_turns`]).
pub fn evaluate_rotations(
    models: &[ImplicitPdf],
    examples: &Examples,
    grid: &RefineOptions,
    views: usize,
    picks: Picks,
    progress: &dyn Progress,
) -> Result<RotationEvaluation, Error> {
    let truths = examples.required_truth_sets()?;
    // The model's distribution is in its own frame: the truth is scored there (LLH, MAAD and
    // Recall MAAD are the same in any frame), and the rotations picked are turned into the
    // camera's.
    let mut predictor = Predictor::ensemble(models, Precision::Model)?.with_views(views)?;
    let turns = examples.frame_turns(models[0].config().rotation_frame)?;
    let argmax_options = ArgmaxOptions {
        refine: *grid,
        ..ArgmaxOptions::default()
    };
    let (mut queries, mut sum_under) = (0, 0.0);
    let (mut llh, mut rotations, mut hypotheses) = (Vec::new(), Vec::new(), Vec::new());
    let (mut maad_deg, mut recall_maad_deg) = (Vec::new(), Vec::new());
    for (i, (truth, turn)) in truths.iter().zip(&turns).enumerate() {
        let truth = &from_camera(truth, turn);
        let crop = to_unit_floats(&examples.crops.get(i as i64));
        let image_term = predictor.image_term(&crop)?;
        let masses = predictor.hierarchical_for(&image_term, grid)?;
        let densities = predictor.log_densities_for(&image_term, truth, &masses)?;
        llh.push(densities.iter().sum::<f64>() / densities.len().max(1) as f64);
        let distribution = cell_distribution(&masses)?;
        maad_deg.push(maad(&distribution, truth)?);
        recall_maad_deg.push(recall_maad(&distribution, truth, RECALL_THRESHOLD)?);
        sum_under += predictor.under_resolution_for(&image_term, &masses)?;
        queries = queries.max(masses.queries);
        if picks.estimates || picks.hypotheses > 0 {
            let best = match picks.ball {
                Some(radius) => masses.heaviest_ball(radius, BALL_CANDIDATES)?.rotation,
                None => {
                    predictor
                        .argmax_from(&image_term, &masses, &argmax_options)?
                        .rotation
                }
            };
            if picks.hypotheses > 0 {
                let picked =
                    masses.rotation_hypotheses(best, picks.hypotheses, picks.hypothesis_spacing)?;
                hypotheses.push(picked.iter().map(|h| turn * h).collect());
            }
            if picks.estimates {
                rotations.push(turn * best);
            }
        }
        progress.advance(1);
    }
    let n = truths.len().max(1) as f64;
    let mean = |values: &[f64]| values.iter().sum::<f64>() / n;
    let scores = Scores {
        images: truths.len(),
        llh: mean(&llh),
        maad_deg: mean(&maad_deg),
        recall_maad_deg: mean(&recall_maad_deg),
        queries_per_image: queries,
        under_resolution: sum_under / n,
    };
    Ok(RotationEvaluation {
        scores,
        llh,
        maad_deg,
        recall_maad_deg,
        estimates: rotations,
        hypotheses,
    })
}

/// The cells and masses of a (hierarchical or dense) evaluation as a `metrics` distribution.
pub fn cell_distribution(masses: &CellMasses) -> Result<Distribution, Error> {
    let cells = masses
        .cells
        .iter()
        .map(|&(level, index)| GridCell { level, index })
        .collect();
    Ok(Distribution::from_cells(cells, masses.masses.clone())?)
}

/// The turn from `model`'s frame into the camera's for `crop` of an image with `intrinsics`
/// ([`ipdf_model::rotation::RotationFrame::to_camera`]).
pub fn crop_turn(
    model: &ImplicitPdf,
    crop: &FileCrop,
    intrinsics: &Intrinsics,
) -> UnitQuaternion<f64> {
    model
        .config()
        .rotation_frame
        .to_camera(&crop.geometry(intrinsics))
}

/// The Implicit-PDF figure of the distribution of `models` (one model, or an ensemble's
/// members) for an 8-bit crop (`[3, S, S]`) on the `level` grid, its image term averaged over
/// `views` test-time views, with `truth` (camera frame) drawn over it; `turn` takes the
/// models' frame into the camera's ([`ipdf_model::rotation::RotationFrame::to_camera`]), so the
/// figure is in the camera's.
pub fn distribution_figure(
    models: &[ImplicitPdf],
    crop: &[u8],
    turn: &UnitQuaternion<f64>,
    truth: &[UnitQuaternion<f64>],
    level: u8,
    views: usize,
    title: &str,
) -> Result<image::RgbImage, Error> {
    let mut predictor = Predictor::ensemble(models, Precision::Model)?.with_views(views)?;
    let size = models[0].config().input_size as usize;
    let grid = Grid::new(level).map_err(|e| Error::option("level", e.to_string()))?;
    let masses = predictor.probabilities(&crop_tensor(crop, size), level)?;
    let rotations: Vec<_> = grid.rotations().iter().map(|r| turn * r).collect();
    plot_distribution(crop, size, &rotations, &masses, truth, title)
}

#[cfg(test)]
mod tests {
    use ipdf_model::ModelConfig;
    use ipdf_model::rotation::RotationFrame;
    use nalgebra::{Unit, Vector3};
    use synth_data::{ObjectKind, SynthObject};
    use tch::Device;

    use super::*;
    use crate::training_data::rendered_examples;

    /// Each crop's turn into the camera's frame, written out from the pinhole model: the turn
    /// about `z × ray` by the angle between `z` and the ray through the crop's centre.
    fn turns_by_hand(examples: &Examples) -> Vec<UnitQuaternion<f64>> {
        examples
            .geometry
            .iter()
            .map(|g| {
                let (k, c) = (&g.intrinsics, &g.crop);
                let ray = Vector3::new(
                    (c.centre_x - 0.5 - k.cx) / k.fx,
                    (c.centre_y - 0.5 - k.cy) / k.fy,
                    1.0,
                )
                .normalize();
                let axis = Unit::new_normalize(Vector3::z().cross(&ray));
                UnitQuaternion::from_axis_angle(&axis, ray.z.acos())
            })
            .collect()
    }

    #[test]
    fn a_line_of_sight_model_is_scored_in_its_frame_and_answers_in_the_camera_frame() {
        let object = SynthObject::built_in(ObjectKind::Box).unwrap();
        let examples = rendered_examples(&object, 3, 16, 5).unwrap();
        let turns = turns_by_hand(&examples);
        assert!(turns.iter().all(|t| t.angle() > 1e-3), "{turns:?}");
        // The same weights (they depend on the seed alone), read in either frame.
        let camera = ModelConfig {
            head_sizes: vec![16, 16],
            ..ModelConfig::small(16)
        };
        let line_of_sight = ModelConfig {
            rotation_frame: RotationFrame::LineOfSight,
            ..camera.clone()
        };
        let in_camera = ImplicitPdf::new(camera, Device::Cpu).unwrap();
        let in_line_of_sight = ImplicitPdf::new(line_of_sight, Device::Cpu).unwrap();
        // The truth turned into the line of sight's frame by hand, for the camera-frame reading.
        let truths = examples.truth_sets.clone().unwrap();
        let turned = Examples {
            crops: examples.crops.shallow_clone(),
            label_sets: examples.label_sets.clone(),
            translation_sets: examples.translation_sets.clone(),
            geometry: examples.geometry.clone(),
            truth_sets: Some(
                truths
                    .iter()
                    .zip(&turns)
                    .map(|(set, turn)| set.iter().map(|r| turn.inverse() * r).collect())
                    .collect(),
            ),
            truth_poses: examples.truth_poses.clone(),
            instances: examples.instances.clone(),
            visible_fractions: examples.visible_fractions.clone(),
            repairs: Default::default(),
            box_crops: 0,
        };
        let picks = Picks {
            estimates: true,
            ball: None,
            hypotheses: 3,
            hypothesis_spacing: 0.5,
        };
        let grid = RefineOptions::to_level(2);
        let scored =
            evaluate_rotations(&[in_line_of_sight], &examples, &grid, 0, picks, &()).unwrap();
        let by_hand = evaluate_rotations(&[in_camera], &turned, &grid, 0, picks, &()).unwrap();
        for (a, b) in [
            (&scored.llh, &by_hand.llh),
            (&scored.maad_deg, &by_hand.maad_deg),
            (&scored.recall_maad_deg, &by_hand.recall_maad_deg),
        ] {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() < 1e-9, "{a:?} against {b:?}");
            }
        }
        for (i, turn) in turns.iter().enumerate() {
            let expected = turn * by_hand.estimates[i];
            assert!(scored.estimates[i].angle_to(&expected) < 1e-9, "crop {i}");
            for (h, g) in scored.hypotheses[i].iter().zip(&by_hand.hypotheses[i]) {
                assert!(h.angle_to(&(turn * g)) < 1e-9, "crop {i}");
            }
        }
    }
}
