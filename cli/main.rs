//! The `afe` command line: list the representations, extract them from WAV files, draw
//! them, stream them from a live source, serve them to remote clients. One module per
//! subcommand; the work itself is done by the library crates.

mod args;
mod batch;
mod bench;
mod devices;
mod error;
mod extract;
mod files;
mod list;
mod locate;
mod memory_reuse;
#[cfg(feature = "plot")]
mod plot;
mod raa;
#[cfg(feature = "view")]
mod serve;
mod stream;
#[cfg(feature = "remote")]
mod subscribe;

use std::io::Write as _;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// `println!` that ends quietly when stdout's reader went away (`afe ... | head`), where
/// `println!` would panic.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::out(&format!("{}\n", format_args!($($arg)*)))
    };
}
pub(crate) use outln;

/// Real-time binaural Auditory Front-End (the Two!Ears AFE representations).
#[derive(Parser)]
#[command(name = "afe", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every request with its parameters, defaults, units and meaning.
    List(list::ListArgs),
    /// Compute representations of a WAV file and save them as float64 arrays in an .npz.
    Extract(extract::ExtractArgs),
    /// Measure processing speed on a WAV file: median wall time of K runs.
    Bench(bench::BenchArgs),
    /// Draw representations of a WAV file: one panel per signal, axes in s and Hz, colour
    /// bars with units (PNG or SVG, by the output's extension).
    #[cfg(feature = "plot")]
    Plot(plot::PlotArgs),
    /// Compute representations of many WAV files into one store (Zarr v3, or one .npz per
    /// file): longest files first on every core, progress, failed files recorded and
    /// skipped, and a second run resumes where a killed one stopped.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Batch(batch::BatchArgs),
    /// The AFE's Room Acoustic Analyzer (afeRAA) of a binaural WAV file: reverberance,
    /// clarity, apparent source width and listener envelopment, unscaled and scaled, with
    /// the levels and ITD fluctuations they come from.
    Raa(raa::RaaArgs),
    /// Where the sources of a binaural WAV file are: azimuths for a head model (a measured
    /// SOFA set or the rigid sphere), with their salience and per frame.
    Locate(locate::LocateArgs),
    /// List the ALSA capture devices (needs a build with `--features alsa`).
    Devices,
    /// Run requests on a live stream (BASS port and block reader): WAV replay, a
    /// synthetic signal or ALSA capture; report compute time per block against its budget.
    Stream(stream::StreamArgs),
    /// Subscribe to requests on an `afe serve` server over Zenoh and report what arrives:
    /// blocks, frames lost, and the latency from the server's port.
    #[cfg(feature = "remote")]
    Subscribe(subscribe::SubscribeArgs),
    /// Serve a live source at real time until stopped (Ctrl-C) or --for, to remote
    /// clients over Zenoh (--listen) and to the live web view on --http, which shows the
    /// representations as they are computed; pages can add and remove requests, change
    /// parameters and listen.
    #[cfg(feature = "view")]
    Serve(serve::ServeArgs),
}

fn main() -> ExitCode {
    // argument errors exit with 1 like every other error (clap's own code is 2); help
    // and version print to stdout and exit with 0
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    if let Command::Bench(_) = cli.command {
        // the runs after the first reuse the memory of the outputs the one before freed,
        // instead of having the kernel zero it afresh; before any thread starts (the
        // interrupt handler's too), so that every thread shares the main heap
        memory_reuse::keep_freed_memory();
    }
    // a limit variable set to a value it does not accept is refused before any work
    if let Err(e) = afe::memory::check_settings() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    install_interrupt_handler();
    let result = match cli.command {
        Command::List(a) => a.run(),
        Command::Extract(a) => a.run(),
        #[cfg(feature = "plot")]
        Command::Plot(a) => a.run(),
        Command::Bench(a) => a.run(),
        Command::Raa(a) => a.run(),
        Command::Locate(a) => a.run(),
        Command::Devices => devices::run(),
        Command::Batch(a) => a.run(),
        Command::Stream(a) => a.run(),
        #[cfg(feature = "remote")]
        Command::Subscribe(a) => a.run(),
        #[cfg(feature = "view")]
        Command::Serve(a) => a.run(),
    };
    // 130: the shells' code for a command stopped by SIGINT
    let interrupted = afe::interrupt::requested();
    match result {
        Ok(()) if interrupted => ExitCode::from(130),
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("error: {msg}");
            ExitCode::from(if interrupted { 130 } else { 1 })
        }
    }
}

/// SIGINT, SIGTERM or SIGHUP: the first asks the running work to stop cleanly (see
/// `afe::interrupt`: no half-written output, a stream saves what it computed, a batch
/// keeps its finished files), a second one quits at once; so does the first while the
/// input is awaited (a FIFO without its writer: nothing is written yet).
fn install_interrupt_handler() {
    let installed = ctrlc::set_handler(|| {
        if afe::interrupt::requested() || afe::interrupt::waiting_on_input() {
            // quitting at once, in the middle of a write perhaps: no .partial file stays
            afe::output::remove_partial_files();
            std::process::exit(130);
        }
        afe::interrupt::request();
        eprintln!("\ninterrupted: stopping cleanly (again to quit at once)");
    });
    if let Err(e) = installed {
        eprintln!("warning: no clean stop on Ctrl-C ({e})");
    }
}

/// Prints `text` to stdout; a reader that went away (`afe list | head`) ends it quietly.
fn out(text: &str) {
    let mut stdout = std::io::stdout().lock();
    let _ = stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush());
}
