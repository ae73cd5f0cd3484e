//! Embedding `afe` in a streaming application: binaural cues frame by frame.
//!
//! Reads a stereo WAV file (default `data/example_binaural.wav`, made by
//! `tools/make_example_wav.py`), places `ild` and `itd` requests with default parameters on
//! one [`afe::Manager`], feeds the signal in 10 ms chunks through `process_chunk` as an
//! audio callback would, and prints, for every new 10 ms frame, the stream time and the
//! ILD (dB, right re left) and ITD (ms, positive = right leads) of the four lowest
//! frequency channels.
//!
//! ```text
//! cargo run --release --example embed [-- path/to/binaural.wav]
//! ```

use std::collections::VecDeque;
use std::error::Error;
use std::path::PathBuf;

use afe::{Manager, ParamMap};

/// Number of lowest-frequency channels shown.
const SHOWN: usize = 4;
/// Chunk length fed to the manager, in seconds.
const CHUNK_S: f64 = 0.01;

/// An error shown by its message: `main` prints an `Err` with `Debug`, which for the
/// library's errors is a struct dump rather than a sentence.
struct Message(String);

impl std::fmt::Debug for Message {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::fmt::Display for Message {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl Error for Message {}

fn main() -> Result<(), Box<dyn Error>> {
    run().map_err(|e| Box::new(Message(e.to_string())) as Box<dyn Error>)
}

/// Reads the file named on the command line and prints its cues frame by frame.
fn run() -> Result<(), Box<dyn Error>> {
    let path = std::env::args_os()
        .nth(1)
        .map_or_else(|| PathBuf::from("data/example_binaural.wav"), PathBuf::from);
    let audio = afe::wav::read_wav(&path)?;
    if audio.channels.len() != 2 {
        return Err(format!(
            "'{}' has {} channel(s); ILD and ITD need a binaural (2-channel) file",
            path.display(),
            audio.channels.len()
        )
        .into());
    }
    let (left, right) = (&audio.channels[0], &audio.channels[1]);

    let mut mgr = Manager::new(audio.fs, 2)?;
    let ild = mgr.add_request("ild", &ParamMap::new())?;
    let itd = mgr.add_request("itd", &ParamMap::new())?;

    // The channels to show: the SHOWN lowest centre frequencies of the (shared) filterbank.
    let (cf_hz, shown) = {
        let signals = mgr.request_signals(ild)?;
        let info = signals.first().ok_or("the ild request has no output")?.info;
        let mut order: Vec<usize> = (0..info.cf_hz().len()).collect();
        order.sort_by(|&a, &b| info.cf_hz()[a].total_cmp(&info.cf_hz()[b]));
        order.truncate(SHOWN);
        (info.cf_hz().to_vec(), order)
    };

    println!(
        "# {}: {:.0} Hz, {:.3} s, chunks of {:.0} ms",
        path.display(),
        audio.fs,
        left.len() as f64 / audio.fs,
        CHUNK_S * 1e3
    );
    let header: Vec<String> = shown
        .iter()
        .map(|&c| format!("{:^15}", format!("{:.1} Hz", cf_hz[c])))
        .collect();
    println!("# centre freq.{}", header.join(" | "));
    let columns: Vec<&str> = shown.iter().map(|_| "ILD/dB   ITD/ms").collect();
    println!("# t/s         {}", columns.join(" | "));

    let chunk = ((CHUNK_S * audio.fs).round() as usize).max(1);
    // Frames not yet printed, per cue (kept separately in case the cues' frame rates
    // ever drift apart; with default parameters both give one frame per 10 ms).
    let mut ild_rows: VecDeque<Vec<f64>> = VecDeque::new();
    let mut itd_rows: VecDeque<Vec<f64>> = VecDeque::new();
    let mut start = 0;
    while start < left.len() {
        let end = (start + chunk).min(left.len());
        mgr.process_chunk(&[&left[start..end], &right[start..end]])?;
        for (handle, rows) in [(ild, &mut ild_rows), (itd, &mut itd_rows)] {
            let signals = mgr.request_signals(handle)?;
            let out = signals.first().ok_or("a request has no output")?;
            rows.extend(
                out.new
                    .rows()
                    .map(|r| shown.iter().map(|&c| r[c]).collect::<Vec<_>>()),
            );
        }
        // Stream time at the end of this chunk: when these frames became available.
        let t = end as f64 / audio.fs;
        while let (Some(l), Some(d)) = (ild_rows.front(), itd_rows.front()) {
            let cells: Vec<String> = l
                .iter()
                .zip(d)
                .map(|(ild_db, itd_s)| format!("{ild_db:>6.2}  {:>7.3}", itd_s * 1e3))
                .collect();
            println!("{t:<13.3} {}", cells.join(" | "));
            ild_rows.pop_front();
            itd_rows.pop_front();
        }
        start = end;
    }
    Ok(())
}
