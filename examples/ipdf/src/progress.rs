//! Progress bars of long commands (on standard error, hidden when it is not a terminal).
use std::sync::OnceLock;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

/// Every bar of the process, so that bars of jobs running at once (the pipeline trains two
/// models together) get a line each.
static BARS: OnceLock<MultiProgress> = OnceLock::new();

/// A bar of `total` steps named `what` (e.g. `"frames"`), showing the rate per second and the
/// time left.
pub fn bar(total: u64, what: &str) -> Bar {
    let style = ProgressStyle::with_template(&format!(
        "{{bar:40}} {{pos}}/{{len}} {what} ({{per_sec}}, {{eta}} left)"
    ))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    Bar(BARS
        .get_or_init(MultiProgress::new)
        .add(ProgressBar::new(total).with_style(style)))
}

/// An indicatif bar as the [`bop_dataset::Progress`] of the library jobs (`synthesize`,
/// `label_dataset`, training and evaluation).
pub struct Bar(pub ProgressBar);

impl Bar {
    /// Removes the bar from the terminal.
    pub fn finish_and_clear(&self) {
        self.0.finish_and_clear();
    }
}

impl bop_dataset::Progress for Bar {
    fn set_total(&self, total: u64, done: u64) {
        self.0.set_length(total);
        self.0.set_position(done);
    }

    fn advance(&self, units: u64) {
        self.0.inc(units);
    }
}
