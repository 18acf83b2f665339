//! The median of a set of scores, as the reports give it.

/// The median (upper middle) of `values`, sorting them; NaN for none.
///
/// ```
/// assert_eq!(ipdf::median::median(&mut [3.0, 1.0, 2.0, 10.0]), 3.0);
/// assert!(ipdf::median::median(&mut []).is_nan());
/// ```
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}
