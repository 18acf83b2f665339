//! Telling apart by colour the poses that depth cannot. A printed box turned half about one of
//! its axes fits the depth as well as the truth does, and so does every turn of a printed can
//! about its axis: the labels found from depth hold them all, and a model trained on them
//! spreads its probability over poses the image tells apart. Where the mesh carries its colours
//! (a texture image or vertex colours) and the image has colour, each label's surface colour,
//! rendered unlit, is correlated with the observed colours inside the mask, and the labels that
//! match clearly worse than the best one are dropped.
use depth_render::{Instance, Lighting};
use nalgebra::Isometry3;
use rayon::prelude::*;

use crate::{ObjectModel, Observation};

/// Fewest pixels (in the mask, where the pose renders the object) a match is computed on.
const MIN_PIXELS: usize = 64;

/// Rendered colours spreading less than this (standard deviation over the compared pixels and
/// channels, 8-bit levels) carry no pattern to match: a uniformly coloured face.
const MIN_SPREAD: f64 = 4.0;

/// The surface's own colour: ambient light only, at full strength.
fn unlit() -> Lighting {
    Lighting {
        ambient: 1.0,
        diffuse: 0.0,
        specular: 0.0,
        ..Lighting::default()
    }
}

/// How well the model's colours at model→camera `pose` match the observed colours inside the
/// instance's mask, from −1 to 1: the correlation, over the mask's pixels where the pose renders
/// the object, of the rendered unlit surface colour with the observed colour, each channel
/// centred on its own mean (so that the light's strength and colour, the camera's exposure and
/// white balance change it little). `None` without a colour image or a coloured mesh, on fewer
/// than 64 such pixels, or where the rendered colours hardly vary there (nothing to match).
pub fn appearance_match(
    model: &ObjectModel,
    observation: &Observation,
    pose: &Isometry3<f64>,
) -> Option<f64> {
    let material = model.appearance.as_ref()?;
    let colour = observation.colour?;
    let camera = &observation.camera;
    let instances = [Instance::new(0, *pose)];
    let rendering = model
        .scene
        .render(camera, &instances, observation.window)
        .ok()?;
    let albedo = model
        .scene
        .shade(
            camera,
            &instances,
            std::slice::from_ref(material),
            &unlit(),
            &rendering,
        )
        .ok()?;
    let window = rendering.window;
    let width = window.width() as usize;
    let mut sums = [ChannelSums::default(); 3];
    for (i, rendered) in albedo.iter().enumerate() {
        let (u, v) = (
            window.u0 as usize + i % width,
            window.v0 as usize + i / width,
        );
        let pixel = v * camera.width as usize + u;
        if rendering.instance[i].is_none() || !observation.mask[pixel] {
            continue;
        }
        for (k, sum) in sums.iter_mut().enumerate() {
            sum.add(f64::from(colour[pixel][k]), f64::from(rendered[k]));
        }
    }
    let n = sums[0].n;
    if n < MIN_PIXELS as f64 {
        return None;
    }
    let (mut covariance, mut observed, mut rendered) = (0.0, 0.0, 0.0);
    for sum in &sums {
        covariance += sum.or - sum.o * sum.r / n;
        observed += sum.oo - sum.o * sum.o / n;
        rendered += sum.rr - sum.r * sum.r / n;
    }
    if (rendered / (3.0 * n)).sqrt() < MIN_SPREAD || observed <= 0.0 {
        return None;
    }
    Some((covariance / (observed * rendered).sqrt()).clamp(-1.0, 1.0))
}

/// Sums over pixels of one channel's observed (`o`) and rendered (`r`) values.
#[derive(Debug, Clone, Copy, Default)]
struct ChannelSums {
    n: f64,
    o: f64,
    r: f64,
    oo: f64,
    rr: f64,
    or: f64,
}

impl ChannelSums {
    fn add(&mut self, o: f64, r: f64) {
        self.n += 1.0;
        self.o += o;
        self.r += r;
        self.oo += o * o;
        self.rr += r * r;
        self.or += o * r;
    }
}

/// The best label's [`appearance_match`] must reach this for the colours to tell labels apart:
/// on the randomised renders of seven textured YCB-Video scans, the true pose matches 0.4–0.9
/// and its look-alikes −0.3–0.3; on a uniformly coloured object every match is noise near 0.
pub const MIN_APPEARANCE_MATCH: f64 = 0.3;

/// Which of the labels whose [`appearance_match`]es are `matches` the colour rule keeps: those
/// within `margin` of the best match, and those whose match cannot be computed; all of them
/// where the best match is under [`MIN_APPEARANCE_MATCH`] or none can be computed (no colour
/// image, a mesh without colours), or `margin` is 0 (off).
pub fn appearance_keeps(matches: &[Option<f64>], margin: f64) -> Vec<bool> {
    let best = matches
        .iter()
        .flatten()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let on = margin > 0.0 && best >= MIN_APPEARANCE_MATCH;
    matches
        .iter()
        .map(|m| !on || m.is_none_or(|m| m >= best - margin))
        .collect()
}

/// The `labels` (model→camera poses with their depth scores, in order) that
/// [`appearance_keeps`] keeps; none is rendered where `margin` is 0 (off).
pub(crate) fn keep_by_appearance(
    model: &ObjectModel,
    observation: &Observation,
    labels: Vec<(Isometry3<f64>, f64)>,
    margin: f64,
) -> Vec<(Isometry3<f64>, f64)> {
    if margin <= 0.0 {
        return labels;
    }
    let matches: Vec<Option<f64>> = labels
        .par_iter()
        .map(|(pose, _)| appearance_match(model, observation, pose))
        .collect();
    labels
        .into_iter()
        .zip(appearance_keeps(&matches, margin))
        .filter_map(|(label, kept)| kept.then_some(label))
        .collect()
}
