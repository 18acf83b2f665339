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

/// How the rotation model and the depth are read on a frame, as `ipdf eval` and `ipdf predict`
/// take them.
#[derive(Debug, clap::Args)]
pub struct FrameArgs {
    /// The depth camera of the frames (`--depth`'s for predict), whose expected errors the
    /// poses found from the rotation model's hypotheses with depth are compared in (as `ipdf
    /// label --sensor`).
    #[arg(long, value_parser = choice::choice::<depth_render::SensorPreset>(), default_value = "kinect")]
    pub sensor: depth_render::SensorPreset,
    /// Average the rotation model's image term over each crop and this many test-time views
    /// of it, zoomed or shifted by 3% of its half-side (at most 8; 0: the crop alone, as the
    /// paper scores; 8 is the mesh pipeline's).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=8))]
    pub views: u8,
}

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

/// Refuses a `--distance NEAR FAR` that is not 0 < NEAR ≤ FAR (finite).
pub fn check_distance(near: f64, far: f64) -> anyhow::Result<()> {
    if !(near.is_finite() && near > 0.0 && far >= near && far.is_finite()) {
        anyhow::bail!("--distance must be two distances with 0 < NEAR ≤ FAR, got {near} {far}");
    }
    Ok(())
}

/// Refuses a `--ball DEG` that is not a radius over 0° and at most 180°.
pub fn check_ball(ball: Option<f64>) -> anyhow::Result<()> {
    if let Some(ball) = ball.filter(|b| !(*b > 0.0 && *b <= 180.0)) {
        anyhow::bail!("--ball {ball}: a radius in degrees, over 0 and at most 180");
    }
    Ok(())
}

/// `--appearance-margin`: a correlation margin in [`pseudo_label::APPEARANCE_MARGINS`] (0:
/// off), refused before any work.
pub fn parse_appearance_margin(text: &str) -> Result<f64, String> {
    let margins = pseudo_label::APPEARANCE_MARGINS;
    match text.trim().parse::<f64>() {
        Ok(margin) if margins.contains(&margin) => Ok(margin),
        _ => {
            let (off, most) = margins.into_inner();
            Err(format!("{text}: a margin from {off} (off) to {most}"))
        }
    }
}

/// A peak learning rate: a positive number, refused before any work.
pub fn parse_learning_rate(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(rate) if rate.is_finite() && rate > 0.0 => Ok(rate),
        _ => Err(format!("{text}: a learning rate over 0")),
    }
}

/// The object of a `--mesh` file in `scale` metres per unit, its repairs warned about, one of
/// an implausible size (a `--mesh-scale` mistake) refused.
pub fn load_mesh(path: &std::path::Path, scale: f64) -> anyhow::Result<synth_data::SynthObject> {
    let (object, repairs) = synth_data::SynthObject::from_mesh_file(path, scale)?;
    warn_repairs(path, &repairs);
    depth_render::check_mesh_size(&object.mesh, path, scale, "--mesh-scale")?;
    Ok(object)
}

/// One warning line on standard error for a mesh that loading repaired.
pub fn warn_repairs(path: &std::path::Path, repairs: &depth_render::MeshRepairs) {
    if !repairs.is_empty() {
        eprintln!("warning: {}: {repairs}", path.display());
    }
}
