//! Progress bars of long commands (on standard error, hidden when it is not a terminal).
use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `total` steps named `what` (e.g. `"frames"`), showing the rate per second and the
/// time left.
pub fn bar(total: u64, what: &str) -> ProgressBar {
    let style = ProgressStyle::with_template(&format!(
        "{{bar:40}} {{pos}}/{{len}} {what} ({{per_sec}}, {{eta}} left)"
    ))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    ProgressBar::new(total).with_style(style)
}
