//! Command-line values of the libraries' named enums (which know nothing of clap): their names
//! are the possible values, listed in `--help` and in errors, and parsed by their `FromStr`.
use clap::builder::{PossibleValuesParser, TypedValueParser};

/// A library enum the command line names.
pub trait Named: Copy + Send + Sync + std::str::FromStr<Err = String> + 'static {
    /// Every value's name.
    fn names() -> Vec<&'static str>;
}

macro_rules! named {
    ($($kind:ty),* $(,)?) => {$(
        impl Named for $kind {
            fn names() -> Vec<&'static str> {
                <$kind>::ALL.iter().map(|value| value.name()).collect()
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

/// The value parser of `T`.
pub fn choice<T: Named>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::names()).try_map(|name| name.parse::<T>())
}
