//! `host-tools`: compile designs to G-code, inspect, preview, resample and send jobs.
use clap::{Parser, Subcommand};
use host_tools::cli;

/// Counts the heap in use, so design scripts run within a memory budget.
#[global_allocator]
static ALLOC: host_tools::mem::Counting = host_tools::mem::Counting;

/// Design compiler and job tools for FDM (and paste) printers.
#[derive(Parser, Debug)]
#[command(name = "host-tools", version, about)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Compile a design script (Rhai) to G-code.
    Compile(cli::compile::Args),
    /// Layers, moves, print time, filament and bounding box of a G-code file.
    Stats(cli::stats::Args),
    /// Render a G-code file to SVG or PNG (top, side and isometric views).
    Preview(cli::preview::Args),
    /// Print a shape onto a face of an existing part (polygon frame).
    Additive(cli::additive::Args),
    /// Grow a single continuous stroke filling a region (differential growth).
    Grow(cli::grow::Args),
    /// Resample a toolpath at a fixed time period.
    Timebased(cli::timebased::Args),
    /// Flag spots deposited on material that has not cured long enough.
    CureCheck(cli::cure_check::Args),
    /// Stream a job to a printer with pause, intervene and resume.
    Send(cli::send::Args),
}

fn main() -> std::process::ExitCode {
    host_tools::mem::keep_freed_memory();
    let cli = Cli::parse();
    let result = match cli.cmd {
        Cmd::Compile(a) => cli::compile::run(a),
        Cmd::Stats(a) => cli::stats::run(a),
        Cmd::Preview(a) => cli::preview::run(a),
        Cmd::Additive(a) => cli::additive::run(a),
        Cmd::Grow(a) => cli::grow::run(a),
        Cmd::Timebased(a) => cli::timebased::run(a),
        Cmd::CureCheck(a) => cli::cure_check::run(a),
        Cmd::Send(a) => cli::send::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
