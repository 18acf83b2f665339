//! `ipdf`: pose-label-free learning of symmetric object orientations, from the command line.
//! See `ipdf --help` and docs/guide.md.
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
    /// Worker threads, rayon's and libtorch's (0: one per core; at most 1024).
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

/// Re-executes this program with the start-up environment it needs, unless the caller set
/// those variables itself; returns only when nothing is missing or the re-execution fails:
/// - glibc backing large allocations by transparent huge pages
///   (`GLIBC_TUNABLES=glibc.malloc.hugetlb=1`, read only at start-up): libtorch allocates and
///   frees large buffers every training step, and their page faults cost more than the
///   arithmetic (the quick preset's training step: 38 images/s without, 60 with, on 2 cores);
/// - libtorch's CPU kernels pinned to AVX2 ([`ipdf_model::REPRODUCIBLE_CPU_KERNELS`]), so that
///   a seed gives the same models and scores on every x86-64 machine with AVX2.
fn reexecute_with_environment() {
    use std::os::unix::process::CommandExt;
    if std::env::var_os(REEXECUTED).is_some() {
        return;
    }
    let mut missing = ipdf_model::missing_kernel_settings();
    if std::env::var_os("GLIBC_TUNABLES").is_none() {
        missing.push(("GLIBC_TUNABLES", "glibc.malloc.hugetlb=1"));
    }
    if missing.is_empty() {
        return;
    }
    let Ok(program) = std::env::current_exe() else {
        return;
    };
    let _error = std::process::Command::new(program)
        .args(std::env::args_os().skip(1))
        .envs(missing)
        .env(REEXECUTED, "1")
        .exec();
}

/// clap's error in one line: its first paragraph (which names the bad flag or value, or lists
/// the missing arguments on the lines after it), its tips (the nearest command or flag), and
/// the `--help` that lists the possible values: the subcommand's own where one was named.
fn usage_error(error: &clap::Error) -> String {
    let text = error.render().to_string();
    let cause: Vec<&str> = text
        .lines()
        .take_while(|line| !line.trim().is_empty())
        .map(str::trim)
        .collect();
    let cause = if cause.is_empty() {
        "error: bad arguments".to_string()
    } else {
        cause.join(" ")
    };
    let tips: String = text
        .lines()
        .filter_map(|line| line.trim().strip_prefix("tip: "))
        .map(|tip| format!("; {tip}"))
        .collect();
    let cli = <Cli as clap::CommandFactory>::command();
    let named = std::env::args().skip(1).find_map(|arg| {
        cli.get_subcommands()
            .find(|command| command.get_name() == arg)
            .map(|command| command.get_name().to_string())
    });
    let help = match named {
        Some(command) => format!("ipdf {command} --help"),
        None => "ipdf --help".into(),
    };
    format!("{cause}{tips} (see {help})")
}

fn main() -> ExitCode {
    reexecute_with_environment();
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
            eprintln!("{}", usage_error(&error));
            return ExitCode::from(2);
        }
    };
    if cli.threads > 0 {
        // libtorch's own threads too, so that `--threads` fixes every thread count that can
        // change a result (see docs/method.md, "Determinism").
        tch::set_num_threads(cli.threads as i32);
    }
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
            // One line, whatever the causes' own formatting; a cause its error already ends
            // with (an error that shows its source) once.
            let mut message = String::new();
            for cause in error.chain() {
                let text = cause.to_string();
                if message.is_empty() {
                    message = text;
                } else if !message.ends_with(&text) {
                    message = format!("{message}: {text}");
                }
            }
            let words: Vec<&str> = message.split_whitespace().collect();
            eprintln!("error: {}", words.join(" "));
            ExitCode::FAILURE
        }
    }
}
