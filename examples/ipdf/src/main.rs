//! `ipdf`: pose-label-free learning of symmetric object orientations, from the command line.
//! See `ipdf --help` and the README.
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

mod commands;

ipdf::keep_freed_pages_allocator!();

/// Learn the full set of symmetric orientations of an object from RGB-D images and its mesh,
/// without pose labels.
#[derive(Debug, Parser)]
#[command(name = "ipdf", version, about, arg_required_else_help = true)]
struct Cli {
    /// Random seed (every command is deterministic given it).
    #[arg(long, global = true, default_value_t = 0)]
    seed: u64,
    /// Worker threads (0: one per core; at most 1024).
    #[arg(
        long,
        global = true,
        default_value_t = 0,
        value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_THREADS)
    )]
    threads: usize,
    /// Print the command's result as one line of JSON.
    #[arg(long, global = true)]
    json: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Write an equivolumetric SO(3) grid (HEALPix × Hopf) as .npy.
    Grid(commands::grid::GridArgs),
    /// Render a mesh at a BOP pose into BOP depth (and RGB, mask) PNGs.
    Render(commands::render::RenderArgs),
    /// Align a source point cloud to a target (FPFH + Fast Global Registration + ICP).
    Register(commands::register::RegisterArgs),
    /// Render a synthetic RGB-D dataset (BOP format) of objects resting on a table.
    Synth(commands::synth::SynthArgs),
    /// Pseudo ground-truth pose sets for every object instance of a BOP dataset, from depth,
    /// masks and meshes (FPFH + FGR + ICP, render-and-compare); GT poses are never read.
    Label(commands::label::LabelArgs),
    /// Train an Implicit-PDF model of one object on single, analytical or pseudo label sets.
    Train(commands::train::TrainArgs),
    /// LLH, MAAD and Recall MAAD of a trained model on a split with ground truth.
    Eval(commands::eval::EvalArgs),
    /// The distribution over SO(3) of a trained model for an object in an image (.npy + JSON).
    Predict(commands::predict::PredictArgs),
    /// Figures: a model's distribution (Implicit-PDF plot) or a run's training curves (PNG).
    Viz(commands::viz::VizArgs),
    /// The whole method on synthetic data: synth → label → train → eval → report.
    Pipeline(commands::pipeline::PipelineArgs),
}

fn run(cli: &Cli) -> Result<serde_json::Value> {
    match &cli.command {
        Command::Grid(args) => commands::grid::run(args),
        Command::Render(args) => commands::render::run(args, cli.seed),
        Command::Register(args) => commands::register::run(args, cli.seed),
        Command::Synth(args) => commands::synth::run(args, cli.seed),
        Command::Label(args) => commands::label::run(args, cli.seed),
        Command::Train(args) => commands::train::run(args, cli.seed),
        Command::Eval(args) => commands::eval::run(args),
        Command::Predict(args) => commands::predict::run(args),
        Command::Viz(args) => commands::viz::run(args),
        Command::Pipeline(args) => commands::pipeline::run(args, cli.seed),
    }
}

/// The most worker threads `--threads` accepts: far more than any machine's cores, while a
/// pool of this size still starts in well under a second (an unbounded count would try to start
/// that many threads and hang).
const MAX_THREADS: u64 = 1024;

/// Set in the environment of the process `ipdf` re-executes itself as.
const REEXECUTED: &str = "IPDF_REEXECUTED";

/// Re-executes this program with glibc backing large allocations by transparent huge pages
/// (`GLIBC_TUNABLES=glibc.malloc.hugetlb=1`, read only at start-up), unless the caller set
/// `GLIBC_TUNABLES` itself: libtorch allocates and frees large buffers every training step, and
/// their page faults cost more than the arithmetic (the quick preset's training step: 38 images/s
/// without, 60 with, on 2 cores). Returns only when that is not done or fails.
fn use_huge_pages() {
    use std::os::unix::process::CommandExt;
    if std::env::var_os("GLIBC_TUNABLES").is_some() || std::env::var_os(REEXECUTED).is_some() {
        return;
    }
    let Ok(program) = std::env::current_exe() else {
        return;
    };
    let _error = std::process::Command::new(program)
        .args(std::env::args_os().skip(1))
        .env("GLIBC_TUNABLES", "glibc.malloc.hugetlb=1")
        .env(REEXECUTED, "1")
        .exec();
}

fn main() -> ExitCode {
    use_huge_pages();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // --help, --version, and no subcommand at all: clap prints the help (and exits 2 for the
        // last).
        Err(error)
            if !error.use_stderr()
                || error.kind()
                    == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand =>
        {
            error.exit()
        }
        Err(error) => {
            // clap's first line names the bad flag; the usage that follows is in --help.
            let text = error.render().to_string();
            let cause = text.lines().next().unwrap_or("error: bad arguments");
            eprintln!("{cause} (see ipdf --help)");
            return ExitCode::from(2);
        }
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cli.threads)
        .build();
    let result = pool
        .map_err(anyhow::Error::from)
        .and_then(|pool| pool.install(|| run(&cli)));
    match result {
        Ok(summary) => {
            if cli.json {
                println!("{summary}");
            } else {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&summary).unwrap_or_default()
                );
            }
            ExitCode::SUCCESS
        }
        Err(error) => {
            // One line, whatever the causes' own formatting.
            let message = format!("{error:#}");
            let words: Vec<&str> = message.split_whitespace().collect();
            eprintln!("error: {}", words.join(" "));
            ExitCode::FAILURE
        }
    }
}
