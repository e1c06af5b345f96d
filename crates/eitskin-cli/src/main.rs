//! The `eitskin` command: thin glue from files and flags to the `eitskin` library.
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

mod bench;
mod calibrate;
mod convergence;
#[cfg(test)]
mod flag_ranges;
mod forward;
mod image;
mod imaging;
mod learn;
mod load;
mod mesh;
mod outputs;
mod plot;
mod progress;
mod ranges;
mod report;
mod run;
mod segment;
mod sensitivity;
mod serve;
mod study;
mod viewer;

use std::path::PathBuf;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// EIT tactile skins: sensor model, forward solver, images, touches and forces.
#[derive(Debug, Parser)]
#[command(
    name = "eitskin",
    version,
    about = "EIT tactile skins: sensor model, forward model, images, touches and forces",
    after_help = "Run `eitskin run` for the live chain on the built-in virtual sensor; `eitskin COMMAND --help` for a command's flags and their ranges."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Cores each image product uses, 1 or 2: with 2 (the default) a helper thread takes part
    /// of each large product while it is free; with 1 every product stays on the calling
    /// thread. The numbers are the same either way.
    #[arg(long, global = true, default_value_t = 2, value_parser = ranges::whole("a number of cores", 1, 2))]
    cores: usize,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print a sensor spec as TOML (the built-in paper sensor unless SPEC is given).
    Spec {
        /// Sensor spec file (TOML); default: the paper's 200 mm square, 16 electrodes.
        spec: Option<PathBuf>,
    },
    /// Mesh the sensor: write the mesh as JSON and a PNG picture with the electrodes marked.
    Mesh(mesh::Args),
    /// Simulate the measurements of the sensor, in protocol order (V at 1 A, i.e. Ω).
    Forward(forward::Args),
    /// Reconstruct a frame against a reference: print its touches, draw the image.
    Image(image::Args),
    /// Write a label image of a frame: background, less or more conductive (the touches' rule).
    Segment(segment::Args),
    /// The paper's Fig. 3: reconstructed peak of one inclusion against its position.
    Sensitivity(sensitivity::Args),
    /// Rerun the paper's study on the virtual sensor: figures, numbers, report.md.
    Study(study::Args),
    /// Fit a per-area calibration from recorded samples and write it (JSON).
    Calibrate(calibrate::CalibrateArgs),
    /// Measure a calibration's force error on samples.
    Evaluate(calibrate::EvaluateArgs),
    /// Learn where (and how hard) presses are from labelled presses: methods side by side, a model file, learning curves.
    Learn(learn::Args),
    /// Write labelled robot presses of the imperfect virtual skin (samples CSV) to learn on.
    RobotPresses(learn::PressesArgs),
    /// Run a sensor live: frames from the virtual sensor, a file or a serial port; touches and forces as JSON lines.
    Run(run::Args),
    /// Serve a fleet of sensors in one process: each an `eitskin run` (FLEET.toml), one Zenoh session, one pool of threads.
    Serve(serve::Args),
    /// Time each stage of the setup chain and print the medians.
    Bench(bench::Args),
    /// Refine the mesh step by step and report how the measurements converge.
    Convergence(convergence::Args),
}

/// The command line, with every flag that takes a value also taking a negative number, so that
/// `--rate -1` reaches the flag's range check instead of reading as an unknown flag `-1`.
fn command() -> clap::Command {
    Cli::command().mut_subcommands(negative_numbers)
}

/// `command` with every flag that takes a value also taking a negative number (see [`command`]).
pub(crate) fn negative_numbers(command: clap::Command) -> clap::Command {
    command.mut_args(|arg| if arg.get_action().takes_values() { arg.allow_negative_numbers(true) } else { arg })
}

fn main() {
    let cli = Cli::from_arg_matches(&command().get_matches()).unwrap_or_else(|e| e.exit());
    eitskin::parallel::set_par(if cli.cores == 1 { eitskin::parallel::Par::Seq } else { eitskin::parallel::Par::Two });
    let result = match cli.command {
        Command::Spec { spec } => load::spec(spec.as_deref()).map(|s| print!("{}", eitskin_io::spec_to_toml(&s))),
        Command::Mesh(args) => mesh::run(args),
        Command::Forward(args) => forward::run(args),
        Command::Image(args) => image::run(args),
        Command::Segment(args) => segment::run(args),
        Command::Sensitivity(args) => sensitivity::run(args),
        Command::Study(args) => study::run(args),
        Command::Calibrate(args) => calibrate::calibrate(args),
        Command::Evaluate(args) => calibrate::evaluate(args),
        Command::Learn(args) => learn::run(args),
        Command::RobotPresses(args) => learn::presses_run(args),
        Command::Run(args) => run::run(args),
        Command::Serve(args) => serve::serve(args),
        Command::Bench(args) => bench::run(args),
        Command::Convergence(args) => convergence::run(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
