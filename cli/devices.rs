//! `afe devices`: the ALSA capture devices.

use crate::error::CliError;
#[cfg(feature = "alsa")]
use crate::outln;

/// Lists the capture devices, one a line.
#[cfg(feature = "alsa")]
pub(crate) fn run() -> Result<(), CliError> {
    let list = afe::bass_source::list_devices()?;
    if list.is_empty() {
        outln!("no ALSA capture device found");
    }
    for d in list {
        outln!("{:<24} {}", d.name, d.description);
    }
    Ok(())
}

#[cfg(not(feature = "alsa"))]
pub(crate) fn run() -> Result<(), CliError> {
    Err(afe::stream::ALSA_OFF.into())
}
