//! `afe raa`: the AFE's Room Acoustic Analyzer (`afeRAA`) of a binaural WAV file.

use std::path::PathBuf;

use afe::raa::{raa, Raa, RaaConstants};

use crate::args::parse_param;
use crate::error::CliError;
use crate::files::{checked_output, read_input};
use crate::outln;

/// `afe raa IN.wav [--json] [-p NAME=VALUE]... [-o OUT.npz]`.
#[derive(clap::Args)]
pub(crate) struct RaaArgs {
    /// Input WAV file, two channels (left, right).
    input: PathBuf,
    /// Print the predictors (`par`) and the scalars of `psi` as JSON, under afeRAA's names.
    #[arg(long)]
    json: bool,
    /// A constant of the RAA, NAME=VALUE (afeRAA's parConf: mu_psi, mu_psi_dip, T_min,
    /// a_P_REV, b_P_REV, ...; the AFE's values by default). Repeatable.
    #[arg(short = 'p', long = "param", value_name = "NAME=VALUE")]
    constants: Vec<String>,
    /// Also write afeRAA's psi (PsiL, PsiR, the streams, ITD, ...) and par to an .npz.
    #[arg(short = 'o', long = "output", value_name = "OUT.npz")]
    output: Option<PathBuf>,
}

impl RaaArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let map = self
            .constants
            .iter()
            .map(|a| parse_param(a))
            .collect::<Result<_, _>>()?;
        let constants = RaaConstants::from_params(&map)?;
        let output = match &self.output {
            Some(o) => Some(checked_output(o, &self.input)?),
            None => None,
        };
        let audio = read_input(&self.input)?;
        let ears: Vec<&[f64]> = audio.channels.iter().map(Vec::as_slice).collect();
        let out = raa(&ears, audio.fs, &constants).map_err(|e| match e {
            afe::raa::RaaError::Afe(afe::Error::Interrupted) => {
                CliError::Message(format!("{e}: nothing was written"))
            }
            e => e.into(),
        })?;
        if let Some(output) = &output {
            let (scalars, par) = npz_scalars(&out);
            let mut entries: Vec<(String, Vec<usize>, &[f64])> = (out.psi.arrays().into_iter())
                .map(|(name, shape, data)| (name.to_string(), shape, data))
                .collect();
            // the 0-d scalars after the arrays, borrowed as those are (Psi is not copied)
            for (name, value) in scalars.iter().chain(&par) {
                entries.push((name.clone(), Vec::new(), std::slice::from_ref(value)));
            }
            output.write(|file| afe::npy::write_npz(file, &entries, None))?;
            eprintln!(
                "wrote {} array(s) to {}",
                entries.len(),
                output.path().display()
            );
        }
        if self.json {
            outln!("{}", out.to_json());
        } else {
            outln!("{}", table(&out));
        }
        Ok(())
    }
}

/// Named 0-d values of an `-o` file.
type Scalars = Vec<(String, f64)>;

/// The 0-d entries of an `-o` file: `psi`'s scalars under afeRAA's names, and each
/// predictor as `par_<name>`.
fn npz_scalars(out: &Raa) -> (Scalars, Scalars) {
    let psi = &out.psi;
    let scalars = [
        ("fs", psi.fs),
        ("numSamples", psi.num_samples as f64),
        ("numBands", psi.num_bands as f64),
        ("itdNumFrames", psi.itd_num_frames as f64),
    ];
    let scalars = scalars.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    let par = (out.par.fields().iter())
        .map(|f| (format!("par_{}", f.name), f.value))
        .collect();
    (scalars, par)
}

/// The predictors as a table: afeRAA's field name, value, unit, meaning; then what they
/// were computed on.
fn table(out: &Raa) -> String {
    let psi = &out.psi;
    let mut lines = vec![format!(
        "{:<6} {:>15}  {:<18} {}",
        "par", "value", "unit", "meaning"
    )];
    for f in out.par.fields() {
        lines.push(format!(
            "{:<6} {:>15.9}  {:<18} {}",
            f.name, f.value, f.unit, f.description
        ));
    }
    let (first, last) = (psi.f.first(), psi.f.last());
    lines.push(format!(
        "\n{} samples at {} Hz ({:.3} s), {} bands from {:.1} to {:.1} Hz, {} ITD frames of \
         50 ms every 25 ms; MU = model units",
        psi.num_samples,
        psi.fs,
        psi.num_samples as f64 / psi.fs,
        psi.num_bands,
        first.copied().unwrap_or(f64::NAN),
        last.copied().unwrap_or(f64::NAN),
        psi.itd_num_frames
    ));
    lines.join("\n")
}
