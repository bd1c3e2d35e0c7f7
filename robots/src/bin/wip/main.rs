//! `wip`: plan, simulate and check the wheeled inverted pendulum. The command line (clap),
//! one file per subcommand; every file format is in docs/formats.md.

mod bench;
mod common;
mod diagnose;
mod generate;
mod params;
mod plan;
mod simulate;
mod track;

use clap::{Parser, Subcommand};
use common::Failure;
use std::process::ExitCode;

/// Plan, simulate and check the wheeled inverted pendulum with DC motors.
///
/// Exit status: 0 success; 1 bad input (a file, a parameter, a size) or a plan not
/// solved, explained in one line on stderr; 2 bad usage. File formats: docs/formats.md.
#[derive(Parser)]
#[command(name = "wip", version, propagate_version = true, max_term_width = 100)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    Plan(plan::PlanArgs),
    Simulate(simulate::SimulateArgs),
    Bench(bench::BenchArgs),
    Diagnose(diagnose::DiagnoseArgs),
    Generate(generate::GenerateArgs),
    Params(params::ParamsArgs),
    Track(track::TrackArgs),
}

/// clap shows the usage with some errors (unknown argument) but not others (invalid value):
/// add the subcommand's usage line where it is missing, so every usage error says how the
/// subcommand is called.
fn print_subcommand_usage(rendered: &str) {
    use clap::CommandFactory;
    if rendered.contains("Usage:") {
        return;
    }
    let Some(sub) = std::env::args().nth(1) else {
        return;
    };
    let mut cli = Cli::command();
    cli.build();
    if let Some(cmd) = cli.find_subcommand_mut(&sub) {
        let usage = cmd.render_usage().to_string();
        robots::progress!("\n{usage}");
    }
}

fn main() -> ExitCode {
    // First, before any thread starts: SIGINT and SIGTERM remove the staging directories.
    robots::io::clean_up_on_signals();
    robots::cli::on_solver_stack(run_command)
}

/// The command line parsed and run.
fn run_command() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Help and version go to stdout with status 0, usage errors to stderr with 2;
            // printing is best-effort (a closed stream must not turn into a panic).
            let _ = e.print();
            if e.use_stderr() {
                print_subcommand_usage(&e.render().to_string());
            }
            return ExitCode::from(e.exit_code().clamp(0, 255) as u8);
        }
    };
    let result = match cli.command {
        Command::Plan(a) => plan::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Generate(a) => generate::run(a),
        Command::Params(a) => params::run(a),
        Command::Track(a) => track::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(e)) => {
            let _ = e.print();
            ExitCode::from(2)
        }
        Err(Failure::Run(m)) => {
            robots::progress!("wip: error: {m}");
            ExitCode::from(1)
        }
    }
}
