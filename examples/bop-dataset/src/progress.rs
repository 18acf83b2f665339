//! How a long job (`synthesize`, `label_dataset`) reports its progress, with no UI type in its
//! signature: the libraries report, the caller draws (the `ipdf` CLI adapts indicatif's bar to
//! it).

/// Progress of a long job, reported by the libraries and drawn by the caller. Reported from
/// worker threads, hence `Sync`.
pub trait Progress: Sync {
    /// The job has `total` units of work, `done` of them already finished (a resumed job).
    fn set_total(&self, _total: u64, _done: u64) {}

    /// `units` more units finished.
    fn advance(&self, units: u64);
}

/// No progress shown.
impl Progress for () {
    fn advance(&self, _units: u64) {}
}
