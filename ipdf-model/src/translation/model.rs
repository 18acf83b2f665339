//! The translation model `F(t, I)`: the unnormalised log-density of the object's translation
//! `t` (camera frame, mm) given its crop and where the crop came from.
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use tch::{Device, Kind, Tensor, nn};

use super::geometry::{FEATURES, crop_factors, crop_features, crop_relative};
use super::{CropGeometry, WorkingVolume};
use crate::encoding::encode_fourier;
use crate::loss::check_label_set;
use crate::network::Network;
use crate::{ModelConfig, ModelError};

/// Where a translation model's density lives and how its queries are normalised; set from the
/// training labels and stored in the checkpoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TranslationSpace {
    /// The box of translations the density covers (mm, camera frame).
    pub volume: WorkingVolume,
    /// The reference extent `E` (mm): the median side of the training crops at their labels'
    /// depth. A query's depth coordinate is 0 where the crop would be `E` wide.
    pub crop_extent: f64,
}

impl TranslationSpace {
    /// The space of a training set: the box around every label padded by a quarter of its
    /// extent and at least one reference extent `E` on each side, `E` the median of the crops'
    /// metric sides at their first label's depth. Refuses empty or non-finite label sets and
    /// bad crop geometry, naming the image.
    pub fn from_labels(
        label_sets: &[Vec<Vector3<f64>>],
        geometry: &[CropGeometry],
    ) -> Result<Self, ModelError> {
        check_translation_sets(label_sets, geometry)?;
        let mut sides: Vec<f64> = label_sets
            .iter()
            .zip(geometry)
            .map(|(set, g)| g.metric_side(set[0].z))
            .collect();
        sides.sort_by(f64::total_cmp);
        let crop_extent = sides[sides.len() / 2];
        let all: Vec<Vector3<f64>> = label_sets.iter().flatten().copied().collect();
        let volume = WorkingVolume::around(&all, 0.25, crop_extent)?;
        let space = Self {
            volume,
            crop_extent,
        };
        space.validate()?;
        Ok(space)
    }

    /// Checks the volume and the reference extent.
    pub fn validate(&self) -> Result<(), ModelError> {
        self.volume.validate()?;
        if !(self.crop_extent.is_finite() && self.crop_extent > 0.0) {
            return Err(ModelError::option(
                "crop_extent",
                format!("{} mm: need > 0", self.crop_extent),
            ));
        }
        Ok(())
    }

    /// The middle depth of the volume, mm.
    pub fn reference_depth(&self) -> f64 {
        0.5 * (self.volume.min[2] + self.volume.max[2])
    }

    /// Where the density of one crop is evaluated: the part of the working volume around the
    /// rays through a square [`CROP_VOLUME_SPAN`] times the crop's side about its centre. An
    /// object's centre projects into its crop, so its density lives there; the box stays as
    /// narrow as the object wherever the crop lies in the image, where the whole volume spans
    /// every position the training objects took (a metre across when they appeared anywhere in
    /// the image), and its cells resolve the density from the first levels of the octree. It
    /// never leaves the working volume, where the model was trained; along an axis where the
    /// rays miss it (a crop where no training object was), the volume's whole extent is kept.
    pub fn crop_volume(&self, geometry: &CropGeometry) -> WorkingVolume {
        let [x_slopes, y_slopes] = span_slopes(geometry);
        let (near, far) = (self.volume.min[2], self.volume.max[2]);
        let within = |[low, high]: [f64; 2], axis: usize| {
            let (min, max) = (self.volume.min[axis], self.volume.max[axis]);
            let from = (low * near).min(low * far).max(min);
            let to = (high * near).max(high * far).min(max);
            if to > from { [from, to] } else { [min, max] }
        };
        let [x0, x1] = within(x_slopes, 0);
        let [y0, y1] = within(y_slopes, 1);
        WorkingVolume {
            min: [x0, y0, near],
            max: [x1, y1, far],
        }
    }
}

/// Whether translation `t` (mm) projects into the square [`CROP_VOLUME_SPAN`] times the crop's
/// side about its centre: on the rays that bound the crop's volume
/// ([`TranslationSpace::crop_volume`]), in front of the camera. The volume is the box around
/// those rays, whose corners far from them hold places no object of the crop could take.
pub fn in_crop_span(geometry: &CropGeometry, t: &Vector3<f64>) -> bool {
    let [x, y] = span_slopes(geometry);
    let inside = |slope: f64, [low, high]: [f64; 2]| (low..=high).contains(&slope);
    t.z > 0.0 && inside(t.x / t.z, x) && inside(t.y / t.z, y)
}

/// `x/z` and `y/z` of the edges of the square [`CROP_VOLUME_SPAN`] times the crop's side about
/// its centre (pixel centres at integers: see `crop_factors`).
fn span_slopes(geometry: &CropGeometry) -> [[f64; 2]; 2] {
    let (k, c) = (&geometry.intrinsics, &geometry.crop);
    let half = 0.5 * CROP_VOLUME_SPAN * c.side;
    let slopes = |centre: f64, principal: f64, focal: f64| {
        [
            (centre - half - principal - 0.5) / focal,
            (centre + half - principal - 0.5) / focal,
        ]
    };
    [
        slopes(c.centre_x, k.cx, k.fx),
        slopes(c.centre_y, k.cy, k.fy),
    ]
}

/// The side of the square, in crop sides, whose rays bound a crop's volume
/// ([`TranslationSpace::crop_volume`]).
pub const CROP_VOLUME_SPAN: f64 = 2.0;

/// Checks translation label sets against their crops: one non-empty set of finite translations
/// in front of the camera per crop, and valid crop geometry.
pub(crate) fn check_translation_sets(
    label_sets: &[Vec<Vector3<f64>>],
    geometry: &[CropGeometry],
) -> Result<(), ModelError> {
    if label_sets.len() != geometry.len() || label_sets.is_empty() {
        return Err(ModelError::LabelSet {
            image: label_sets.len().min(geometry.len()),
            reason: format!(
                "{} label sets for {} crops (need one per crop, at least one)",
                label_sets.len(),
                geometry.len()
            ),
        });
    }
    for (image, (set, g)) in label_sets.iter().zip(geometry).enumerate() {
        g.validate(image)?;
        check_label_set(
            image,
            set,
            |t| !t.iter().all(|v| v.is_finite()) || t.z <= 0.0,
            |i, t| {
                format!(
                    "translation {i} {:?} mm is not finite or not in front of the camera",
                    t.as_slice()
                )
            },
        )?;
    }
    Ok(())
}

/// A translation model's shape and its space; stored in every translation checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TranslationConfig {
    /// The network: encoder, crop size, Fourier components of the query's crop-relative
    /// coordinates, head widths, seed.
    pub network: ModelConfig,
    /// The working volume and query normalisation.
    pub space: TranslationSpace,
}

impl TranslationConfig {
    /// A small network for quick CPU runs and tests: [`ModelConfig::small`], whose 3 Fourier
    /// components encode translations as they do rotations. Their finest period, 2π/4 in the
    /// depth coordinate, is a 120% change of depth. Trained on the quick preset's 800 crops per
    /// object, 6 components (finest period a 10% change) missed new crops more often and by
    /// more: on 200 new frames the box's mean error was 19 mm against 17 with 3, the can's 8
    /// against 3.5, the bowl's 10 against 2.6, at LLHs higher by 0.3 nats at most.
    pub fn small(input_size: i64, space: TranslationSpace) -> Self {
        Self {
            network: ModelConfig::small(input_size),
            space,
        }
    }

    /// Checks the network's fields and the space.
    pub fn validate(&self) -> Result<(), ModelError> {
        self.network.validate()?;
        self.space.validate()
    }
}

/// The length of the encoded crop-relative query: `6F`, or 3 for `F = 0`.
const fn encoded_len(components: i64) -> i64 {
    if components == 0 { 3 } else { 6 * components }
}

/// An implicit translation density: `F(t, I)`, the unnormalised log-density of translation `t`
/// (mm, camera frame) given crop `I` and its [`CropGeometry`], with
/// `p(t | I) = exp F(t, I) / ∫_V exp F(t', I) dt'` over the working volume `V` (density per
/// mm³). The image term sees the crop's features and where the crop came from (the direction
/// of its centre's ray and its scale); the query term sees `t` in the crop's own coordinates
/// (see `crop_relative`), Fourier-encoded. Same head as the rotation model.
pub struct TranslationPdf {
    network: Network,
    config: TranslationConfig,
}

impl std::fmt::Debug for TranslationPdf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.network.debug(f, "TranslationPdf", &self.config)
    }
}

impl TranslationPdf {
    /// A freshly initialised model on `device`; its weights depend only on
    /// `config.network.seed`.
    pub fn new(config: TranslationConfig, device: Device) -> Result<Self, ModelError> {
        config.validate()?;
        let query_len = encoded_len(config.network.fourier_components);
        let network = Network::new(&config.network, FEATURES, query_len, device);
        Ok(Self { network, config })
    }

    /// The configuration the model was built from.
    pub fn config(&self) -> &TranslationConfig {
        &self.config
    }

    /// The working volume and query normalisation.
    pub fn space(&self) -> &TranslationSpace {
        &self.config.space
    }

    /// The device holding the parameters.
    pub fn device(&self) -> Device {
        self.network.device()
    }

    /// The parameters' element kind.
    pub fn kind(&self) -> Kind {
        self.network.kind()
    }

    /// The parameters (`encoder.` in torchvision names, `head.*`).
    pub fn var_store(&self) -> &nn::VarStore {
        self.network.var_store()
    }

    /// The parameters, mutably.
    pub fn var_store_mut(&mut self) -> &mut nn::VarStore {
        self.network.var_store_mut()
    }

    /// Checks crops `[B, 3, S, S]` and their geometry (one per crop, valid).
    pub fn check_inputs(
        &self,
        images: &Tensor,
        geometry: &[CropGeometry],
    ) -> Result<(), ModelError> {
        self.network.check_images(images)?;
        let batch = images.size()[0] as usize;
        if geometry.len() != batch {
            return Err(ModelError::CropGeometry {
                image: geometry.len().min(batch),
                reason: format!("{} crop geometries for {batch} crops", geometry.len()),
            });
        }
        for (image, g) in geometry.iter().enumerate() {
            g.validate(image)?;
        }
        Ok(())
    }

    /// The image term `[B, H]` of crops `[B, 3, S, S]` (values in `[0, 1]`) cut with
    /// `geometry`; `train` selects batch statistics in batch norm.
    pub fn image_term(
        &self,
        images: &Tensor,
        geometry: &[CropGeometry],
        train: bool,
    ) -> Result<Tensor, ModelError> {
        self.check_inputs(images, geometry)?;
        let (kind, device) = (self.kind(), self.device());
        let features = self.network.features(images, train)?;
        let space = &self.config.space;
        let placement = crop_features(
            geometry,
            space.crop_extent,
            space.reference_depth(),
            device,
            kind,
        );
        Ok(self
            .network
            .head()
            .image_term(&Tensor::cat(&[features, placement], 1)))
    }

    /// The per-crop factors `[B, 5]` that put translations in each crop's coordinates (for
    /// [`TranslationPdf::query_term`]).
    pub fn crop_factors(&self, geometry: &[CropGeometry]) -> Tensor {
        crop_factors(
            geometry,
            self.config.space.crop_extent,
            self.device(),
            self.kind(),
        )
    }

    /// The query term `[…, H]` of translations `[…, 3]` (mm) for crop factors broadcastable to
    /// `[…, 5]` (`[B, 1, 5]` with translations `[B, N, 3]`).
    pub fn query_term(&self, translations: &Tensor, factors: &Tensor) -> Tensor {
        let relative = crop_relative(&translations.to_kind(self.kind()), factors);
        self.network.head().query_term(&encode_fourier(
            &relative,
            self.config.network.fourier_components,
        ))
    }

    /// `F(t, I)` for broadcastable terms (image `[B, 1, H]` with queries `[B, N, H]` gives
    /// `[B, N]`).
    pub fn scores(&self, image_term: &Tensor, query_term: &Tensor) -> Tensor {
        self.network.head().scores(image_term, query_term)
    }
}
