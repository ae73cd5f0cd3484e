//! The CLI's one error type.

/// Everything the CLI reports: each error as the crate that found it says it, or a
/// usage error of the command line itself.
#[derive(Debug, thiserror::Error)]
pub(crate) enum CliError {
    #[error(transparent)]
    Afe(#[from] afe::Error),
    #[error(transparent)]
    Raa(#[from] afe::raa::RaaError),
    #[error(transparent)]
    Batch(#[from] afe_batch::BatchError),
    #[error(transparent)]
    Stream(#[from] afe::stream::StreamError),
    #[error(transparent)]
    Output(#[from] afe::output::OutputError),
    #[error(transparent)]
    Wav(#[from] afe::wav::WavError),
    #[error(transparent)]
    Source(#[from] afe::bass_source::Error),
    #[error(transparent)]
    Spatial(#[from] afe_spatial::SpatialError),
    #[cfg(feature = "view")]
    #[error(transparent)]
    View(#[from] afe_view::ViewError),
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Plot(#[from] afe_plot::PlotError),
    #[cfg(feature = "remote")]
    #[error(transparent)]
    Remote(#[from] afe_net::RemoteError),
    #[error("{0}")]
    Message(String),
}

impl From<String> for CliError {
    fn from(msg: String) -> Self {
        CliError::Message(msg)
    }
}

impl From<&str> for CliError {
    fn from(msg: &str) -> Self {
        CliError::Message(msg.to_string())
    }
}
