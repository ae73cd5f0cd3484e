//! The files of a command: its WAV input, and outputs checked before the work and
//! written whole after it.

use std::path::Path;

use afe::output::OutputFile;
use afe::wav::{Audio, WavBlocks};
use afe_spatial::{HeadYaw, Platform};

use crate::error::CliError;

/// Opens a WAV file that afe can process: mono or two channels, not empty.
pub(crate) fn open_input(input: &Path) -> Result<WavBlocks, CliError> {
    Ok(afe::wav::open_input(input)?)
}

/// Reads a whole WAV file that afe can process.
pub(crate) fn read_input(input: &Path) -> Result<Audio, CliError> {
    Ok(open_input(input)?.read_all()?)
}

/// Reads every channel of a whole WAV file, however many it has (a robot's capture).
pub(crate) fn read_capture(input: &Path) -> Result<Audio, CliError> {
    Ok(afe::wav::open_capture(input)?.read_all()?)
}

/// Largest platform descriptor read, bytes.
const PLATFORM_FILE_MAX_BYTES: u64 = 1 << 20;

/// The platform descriptor at `path`, read within [`PLATFORM_FILE_MAX_BYTES`] and checked.
pub(crate) fn read_platform(path: &Path) -> Result<Platform, CliError> {
    let text = afe::bounded_read::read_text(path, PLATFORM_FILE_MAX_BYTES)
        .map_err(|e| CliError::Message(format!("cannot read {}: {e}", path.display())))?;
    let folder = path.parent().unwrap_or(Path::new("."));
    Platform::parse(&text, folder)
        .map_err(|e| CliError::Message(format!("{}: {e}", path.display())))
}

/// Largest yaw track read, bytes: hours of a 100-Hz track, and a bound on what a wrong
/// path (`/dev/zero`, a WAV file) can make the command read.
const YAW_FILE_MAX_BYTES: u64 = 64 << 20;

/// The head's yaw track at `path`: a CSV of `t_s,yaw_deg` rows (`--head-yaw`).
pub(crate) fn read_head_yaw(path: &Path) -> Result<HeadYaw, CliError> {
    let text = afe::bounded_read::read_text(path, YAW_FILE_MAX_BYTES)
        .map_err(|e| CliError::Message(format!("cannot read {}: {e}", path.display())))?;
    HeadYaw::parse_csv(&text).map_err(|e| CliError::Message(format!("{}: {e}", path.display())))
}

/// A platform descriptor as the JSON that `afe serve` publishes and the page shows.
#[cfg(feature = "view")]
pub(crate) fn platform_json(platform: &Platform) -> Result<serde_json::Value, CliError> {
    serde_json::to_value(platform)
        .map_err(|e| CliError::Message(format!("the platform descriptor: {e}")))
}

/// Checks `path` as an output of a run reading `input` (see [`OutputFile::check`]).
pub(crate) fn checked_output(path: &Path, input: &Path) -> Result<OutputFile, CliError> {
    let out = OutputFile::check(path)?;
    out.check_not_input(input)?;
    Ok(out)
}

/// Saves every recorded signal as a float64 array `<request>_<ear>` in an .npz, with
/// their descriptions in its `afe_metadata` entry.
pub(crate) fn save(rec: &afe::Recorder, output: &OutputFile) -> Result<(), CliError> {
    output.write(|file| rec.write_npz(file))?;
    report_saved(rec, output);
    Ok(())
}

/// Says on stderr which arrays went to `output`.
pub(crate) fn report_saved(rec: &afe::Recorder, output: &OutputFile) {
    eprintln!(
        "wrote {} array(s) to {}: {}",
        rec.signals().len(),
        output.path().display(),
        rec.signals()
            .iter()
            .map(|s| format!("{} {:?}", s.key, s.shape()))
            .collect::<Vec<_>>()
            .join(", ")
    );
}
