//! One module per `ipdf` subcommand.
mod choice;
pub mod eval;
pub mod grid;
pub mod label;
pub mod pipeline;
pub mod predict;
pub mod register;
pub mod render;
pub mod synth;
pub mod train;
pub mod viz;

/// Refuses a `flag` path that does not end in `.extension` (any case): the file is written in
/// that format whatever its name, so another ending would mislabel it. `what` says what is
/// written.
pub fn check_extension(
    flag: &str,
    path: &std::path::Path,
    extension: &str,
    what: &str,
) -> anyhow::Result<()> {
    let matches = path
        .extension()
        .is_some_and(|found| found.eq_ignore_ascii_case(extension));
    if !matches {
        anyhow::bail!(
            "{flag} {}: {what} is written as .{extension}, so the file must end in .{extension}",
            path.display()
        );
    }
    Ok(())
}

/// One warning line on standard error for a mesh that loading repaired.
pub fn warn_repairs(path: &std::path::Path, repairs: &depth_render::MeshRepairs) {
    if !repairs.is_empty() {
        eprintln!("warning: {}: {repairs}", path.display());
    }
}
