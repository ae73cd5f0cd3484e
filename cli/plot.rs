//! `afe plot`: a WAV file's representations drawn, one panel per signal.

use std::path::{Path, PathBuf};

use afe::extract::{run_wav, Job};
use afe::Manager;

use crate::args::Requests;
use crate::error::CliError;
use crate::files::{checked_output, open_input};
use crate::outln;

/// `afe plot IN.wav -r ... -o FIG.png`.
#[derive(clap::Args)]
pub(crate) struct PlotArgs {
    /// Input WAV file (mono or two-channel binaural).
    input: PathBuf,
    #[command(flatten)]
    requests: Requests,
    /// Time (s) at which correlations, modulation spectra and DUET histograms are
    /// drawn (default: the middle of the signal).
    #[arg(long, value_name = "S")]
    at: Option<f64>,
    /// Audio-rate signals of several channels (filterbank, inner hair cell, adaptation)
    /// as images of their largest magnitude per pixel column, in dB, instead of stacked
    /// waveforms.
    #[arg(long)]
    images: bool,
    /// Figure width in pixels.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u32).range(300..=10_000))]
    width: u32,
    /// Output figure, .png or .svg.
    #[arg(short = 'o', long = "output", value_name = "FIG.png")]
    output: PathBuf,
}

impl PlotArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let (requests, params) = self.requests.load()?;
        let job = Job {
            requests,
            params,
            ..Job::default()
        };
        let layout = afe_plot::Layout {
            width: self.width,
            at_s: self.at,
            waveforms: !self.images,
            ..afe_plot::Layout::default()
        };
        plot(&self.input, &job, &layout, &self.output)
    }
}

fn plot(input: &Path, job: &Job, layout: &afe_plot::Layout, output: &Path) -> Result<(), CliError> {
    let format = afe_plot::Format::of(output)?;
    let output = checked_output(output, input)?;
    let mut wav = open_input(input)?;
    let mut mgr = Manager::new(wav.fs(), wav.channels())?;
    let rec = run_wav(&mut mgr, job, &mut wav)?;
    let figure = afe_plot::render(&rec, format, layout)?;
    output.write(|file| file.write_all(&figure))?;
    outln!(
        "drew {} panel(s) to {}",
        rec.signals().len(),
        output.path().display()
    );
    Ok(())
}
