//! Command-line values of the libraries' named enums (which know nothing of clap): their names
//! are the possible values, listed in `--help` and in errors.
use clap::builder::{PossibleValuesParser, TypedValueParser};

/// A library enum the command line names: every value (`ALL`) and its `name()`.
pub trait Named: Copy + Send + Sync + 'static {
    /// Every value.
    fn all() -> &'static [Self];
    /// The value's name on the command line and in files.
    fn name(self) -> &'static str;
}

macro_rules! named {
    ($($kind:ty),* $(,)?) => {$(
        impl Named for $kind {
            fn all() -> &'static [Self] {
                &<$kind>::ALL
            }

            fn name(self) -> &'static str {
                <$kind>::name(self)
            }
        }
    )*};
}

named!(
    synth_data::ObjectKind,
    synth_data::Variant,
    pseudo_label::Strategy,
    ipdf::training_data::LabelSource,
    ipdf::npy::RotationFormat,
    ipdf::pipeline::Preset,
);

/// The value parser of `T`: one of its names.
pub fn choice<T: Named>() -> impl TypedValueParser<Value = T> {
    let names: Vec<&'static str> = T::all().iter().map(|value| value.name()).collect();
    PossibleValuesParser::new(names).try_map(|name| {
        T::all()
            .iter()
            .copied()
            .find(|value| value.name() == name)
            .ok_or_else(|| format!("{name:?} is not a possible value"))
    })
}
