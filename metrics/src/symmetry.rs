//! Symmetry groups of objects, in the form of BOP's `models_info.json`.
use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use serde_json::{Value, json};
use so3_grid::{
    geodesic_distance, rotation_from_axis_angle, rotation_from_matrix, rotation_to_matrix,
};

use crate::MetricsError;

/// Steps a continuous symmetry is discretised into (the paper's 200 orientations).
pub const CONTINUOUS_STEPS: usize = 200;

/// Rotations closer than this (radians) are the same symmetry.
const SAME_ROTATION: f64 = 1e-6;

/// Whether `a` and `b` are within [`SAME_ROTATION`] of each other: the test of
/// [`geodesic_distance`] (angle `4·atan2(|a − b|, |a + b|)`, quaternions in one hemisphere)
/// without its arctangent, `|a − b|² ≤ tan²(SAME_ROTATION / 4)·|a + b|²`. The deduplication of a
/// can's 400 symmetry rotations compares 80,000 pairs; with `atan2` that was a fifth of a
/// training run's set-up.
fn same_rotation(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> bool {
    let (a, mut b) = (a.as_ref().coords, b.as_ref().coords);
    if a.dot(&b) < 0.0 {
        b = -b;
    }
    let tangent = (SAME_ROTATION / 4.0).tan();
    (a - b).norm_squared() <= tangent * tangent * (a + b).norm_squared()
}

/// Rotational symmetry about an axis through a point, in model coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct ContinuousSymmetry {
    /// The symmetry axis (model frame).
    pub axis: Unit<Vector3<f64>>,
    /// A point on the axis, in the model's units (BOP files: mm).
    pub offset: Vector3<f64>,
}

/// The proper symmetries of an object: transforms `S` with `mesh(S·x) = mesh(x)`, so that a pose
/// `R` is indistinguishable from every `R·S`.
///
/// `discrete` lists the non-identity discrete symmetries (translations in the model's units);
/// `continuous` the symmetry axes, combined with every discrete one (a can: its axis plus the
/// flip). BOP's `symmetries_discrete` / `symmetries_continuous` fields map one to one.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SymmetryGroup {
    /// Discrete symmetries other than the identity.
    pub discrete: Vec<Isometry3<f64>>,
    /// Continuous symmetry axes.
    pub continuous: Vec<ContinuousSymmetry>,
}

impl SymmetryGroup {
    /// No symmetry but the identity.
    pub fn none() -> Self {
        Self::default()
    }

    /// The symmetry rotations, identity first: every discrete symmetry (and the identity)
    /// composed with `continuous_steps` rotations about each continuous axis; duplicates within
    /// 1e-6 rad removed.
    pub fn rotations(&self, continuous_steps: usize) -> Vec<UnitQuaternion<f64>> {
        let mut out = vec![UnitQuaternion::identity()];
        out.extend(self.discrete.iter().map(|s| s.rotation));
        for axis in &self.continuous {
            let base = out.clone();
            for step in 1..continuous_steps.max(1) {
                let angle = std::f64::consts::TAU * step as f64 / continuous_steps as f64;
                let turn = UnitQuaternion::from_axis_angle(&axis.axis, angle);
                out.extend(base.iter().map(|d| turn * d));
            }
        }
        let mut unique: Vec<UnitQuaternion<f64>> = Vec::with_capacity(out.len());
        for q in out {
            if unique.iter().all(|u| !same_rotation(u, &q)) {
                unique.push(q);
            }
        }
        unique
    }

    /// Every orientation indistinguishable from `rotation` (model→camera): `rotation · S` for
    /// each symmetry rotation `S`, continuous axes discretised into [`CONTINUOUS_STEPS`].
    pub fn expand(&self, rotation: &UnitQuaternion<f64>) -> Vec<UnitQuaternion<f64>> {
        self.rotations(CONTINUOUS_STEPS)
            .iter()
            .map(|s| rotation * s)
            .collect()
    }

    /// The symmetry classes: the identity and each discrete symmetry not already on the orbit
    /// of an earlier one under the continuous axes (a half-turn about a can's own axis is no
    /// class of its own), as rotations.
    pub fn classes(&self) -> Vec<UnitQuaternion<f64>> {
        let mut classes = vec![UnitQuaternion::identity()];
        for symmetry in &self.discrete {
            let candidate = symmetry.rotation;
            if classes
                .iter()
                .all(|base| self.orbit_distance(base, &candidate) > SAME_ROTATION)
            {
                classes.push(candidate);
            }
        }
        classes
    }

    /// The geodesic distance (radians) from `rotation` to the orbit of `base` under the
    /// continuous axes, `{R(axis, θ) · base}`: exact for one axis (in closed form: for
    /// `q = rotation · base⁻¹ = (w, v)`, `2·acos √(w² + (v·axis)²)`), over
    /// [`CONTINUOUS_STEPS`] angles for several, `angle(base⁻¹ · rotation)` for none.
    pub fn orbit_distance(
        &self,
        base: &UnitQuaternion<f64>,
        rotation: &UnitQuaternion<f64>,
    ) -> f64 {
        let q = rotation * base.inverse();
        match self.continuous.as_slice() {
            [] => geodesic_distance(base, rotation),
            [axis] => {
                let (w, v) = (q.w, q.imag());
                let along = v.dot(&axis.axis);
                2.0 * (w * w + along * along).sqrt().min(1.0).acos()
            }
            _ => {
                let turns = Self {
                    discrete: Vec::new(),
                    continuous: self.continuous.clone(),
                };
                turns
                    .rotations(CONTINUOUS_STEPS)
                    .iter()
                    .map(|turn| geodesic_distance(&(turn * base), rotation))
                    .fold(f64::INFINITY, f64::min)
            }
        }
    }

    /// For each of [`SymmetryGroup::classes`], the geodesic distance (radians) from `rotation`
    /// to that class's members in the symmetry set of `truth` (`truth · R(axis, θ) · base`).
    /// Their minimum is the distance to the nearest pose indistinguishable from `truth`.
    pub fn class_distances(
        &self,
        truth: &UnitQuaternion<f64>,
        rotation: &UnitQuaternion<f64>,
    ) -> Vec<f64> {
        let relative = truth.inverse() * rotation;
        self.classes()
            .iter()
            .map(|base| self.orbit_distance(base, &relative))
            .collect()
    }

    /// Reads the symmetry fields of one object's entry of BOP `models_info.json`; absent fields
    /// mean no symmetry of that kind. Errors name the field, e.g. `symmetries_discrete[1]`.
    pub fn from_bop_json(model_info: &Value) -> Result<Self, MetricsError> {
        let mut group = Self::none();
        for (i, entry) in list(model_info, "symmetries_discrete")?.iter().enumerate() {
            let field = format!("symmetries_discrete[{i}]");
            let m: [f64; 16] = numbers(entry, &field)?;
            let rotation = [m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]];
            let rotation = rotation_from_matrix(&rotation).map_err(|e| invalid(&field, e))?;
            let translation = Translation3::new(m[3], m[7], m[11]);
            group
                .discrete
                .push(Isometry3::from_parts(translation, rotation));
        }
        for (i, entry) in list(model_info, "symmetries_continuous")?
            .iter()
            .enumerate()
        {
            let field = format!("symmetries_continuous[{i}]");
            let get = |key: &str| {
                let f = format!("{field}.{key}");
                let v = entry.get(key).ok_or_else(|| invalid(&f, "missing"))?;
                numbers::<3>(v, &f).map(Vector3::from)
            };
            let axis = Unit::try_new(get("axis")?, 1e-12)
                .ok_or_else(|| invalid(&format!("{field}.axis"), "zero length"))?;
            group.continuous.push(ContinuousSymmetry {
                axis,
                offset: get("offset")?,
            });
        }
        Ok(group)
    }

    /// The `symmetries_discrete` / `symmetries_continuous` fields of a BOP `models_info.json`
    /// entry (empty lists are left out, as BOP does).
    pub fn to_bop_json(&self) -> Value {
        let mut fields = serde_json::Map::new();
        if !self.discrete.is_empty() {
            let discrete: Vec<Value> = self
                .discrete
                .iter()
                .map(|s| {
                    let (r, t) = (rotation_to_matrix(&s.rotation), s.translation.vector);
                    json!([
                        r[0], r[1], r[2], t.x, r[3], r[4], r[5], t.y, r[6], r[7], r[8], t.z, 0.0,
                        0.0, 0.0, 1.0
                    ])
                })
                .collect();
            fields.insert("symmetries_discrete".into(), discrete.into());
        }
        if !self.continuous.is_empty() {
            let continuous: Vec<Value> = self
                .continuous
                .iter()
                .map(|c| json!({"axis": c.axis.as_slice(), "offset": c.offset.as_slice()}))
                .collect();
            fields.insert("symmetries_continuous".into(), continuous.into());
        }
        Value::Object(fields)
    }

    /// The group of rotations about the origin: `discrete` rotations other than the identity
    /// and axes of revolution through the origin (as `depth_render::ShapeSymmetry` gives them).
    pub fn about_origin(discrete: &[UnitQuaternion<f64>], axes: &[Unit<Vector3<f64>>]) -> Self {
        Self {
            discrete: discrete
                .iter()
                .map(|&rotation| Isometry3::from_parts(Translation3::identity(), rotation))
                .collect(),
            continuous: axes
                .iter()
                .map(|&axis| ContinuousSymmetry {
                    axis,
                    offset: Vector3::zeros(),
                })
                .collect(),
        }
    }

    /// A group of `n`-fold rotations about `axis` (`n ≥ 1`; `n = 1` is no symmetry).
    pub fn cyclic(axis: &Vector3<f64>, n: u32) -> Result<Self, MetricsError> {
        let discrete = (1..n.max(1))
            .map(|k| {
                let angle = std::f64::consts::TAU * f64::from(k) / f64::from(n);
                let rotation = rotation_from_axis_angle(axis, angle)?;
                Ok(Isometry3::from_parts(Translation3::identity(), rotation))
            })
            .collect::<Result<_, MetricsError>>()?;
        Ok(Self {
            discrete,
            continuous: Vec::new(),
        })
    }
}

fn invalid(field: &str, reason: impl ToString) -> MetricsError {
    MetricsError::InvalidSymmetry {
        field: field.to_string(),
        reason: reason.to_string(),
    }
}

fn list<'a>(info: &'a Value, key: &str) -> Result<&'a [Value], MetricsError> {
    match info.get(key) {
        None | Some(Value::Null) => Ok(&[]),
        Some(Value::Array(items)) => Ok(items),
        Some(_) => Err(invalid(key, "expected a list")),
    }
}

fn numbers<const N: usize>(value: &Value, field: &str) -> Result<[f64; N], MetricsError> {
    let items = value
        .as_array()
        .ok_or_else(|| invalid(field, format!("expected {N} numbers")))?;
    if items.len() != N {
        return Err(invalid(
            field,
            format!("expected {N} numbers, got {}", items.len()),
        ));
    }
    let mut out = [0.0; N];
    for (slot, item) in out.iter_mut().zip(items) {
        *slot = item
            .as_f64()
            .filter(|v| v.is_finite())
            .ok_or_else(|| invalid(field, format!("{item} is not a finite number")))?;
    }
    Ok(out)
}
