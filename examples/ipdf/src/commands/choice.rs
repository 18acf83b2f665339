//! Command-line values of the libraries' named enums (which know nothing of clap): their names
//! are the possible values, listed in `--help` and in errors.
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

/// A library enum the command line names: every value (`ALL`) and its `name()`.
pub trait Named: Copy + Send + Sync + 'static {
    /// Every value.
    fn all() -> &'static [Self];
    /// The value's name on the command line and in files.
    fn name(self) -> &'static str;
    /// What the value means, for `--help`, where its flag's own help does not say.
    fn help(self) -> Option<&'static str> {
        None
    }
}

/// `Named` for each type, from its `ALL` and `name()`; `=> f` adds `f(value)` as the help.
macro_rules! named {
    ($($kind:ty $(=> $help:path)?),* $(,)?) => {$(
        impl Named for $kind {
            fn all() -> &'static [Self] {
                &<$kind>::ALL
            }

            fn name(self) -> &'static str {
                <$kind>::name(self)
            }

            $(fn help(self) -> Option<&'static str> {
                Some($help(self))
            })?
        }
    )*};
}

named!(
    synth_data::ObjectKind => synth_data::ObjectKind::description,
    synth_data::Variant,
    synth_data::Placement,
    depth_render::SensorPreset => depth_render::SensorPreset::description,
    pseudo_label::Strategy,
    ipdf::training_data::LabelSource,
    ipdf::training_data::CropSource,
    ipdf::training::Target,
    ipdf_model::rotation::RotationFrame,
    ipdf::eval::Truth,
    ipdf::npy::RotationFormat,
    ipdf::pipeline::Preset => ipdf::pipeline::Preset::description,
);

/// The value parser of `T`: one of its names.
pub fn choice<T: Named>() -> impl TypedValueParser<Value = T> {
    let values = T::all().iter().map(|&value| {
        let possible = PossibleValue::new(value.name());
        match value.help() {
            Some(help) => possible.help(help),
            None => possible,
        }
    });
    PossibleValuesParser::new(values).try_map(|name| {
        T::all()
            .iter()
            .copied()
            .find(|value| value.name() == name)
            .ok_or_else(|| format!("{name:?} is not a possible value"))
    })
}
