//! What an input must give (a robot's platform descriptor says so): its channels and
//! rate, checked where the source opens, with an error naming who declares it.

/// What a stream's source must give, and who declares it.
#[derive(Debug, Clone, PartialEq)]
pub struct ExpectedSource {
    /// Who declares it, as the error names it (`'seed robot'`).
    pub by: String,
    /// Its channels.
    pub channels: usize,
    /// Its rate, Hz.
    pub fs_hz: f64,
}

impl ExpectedSource {
    /// Checks a source of `channels` channels at `fs_hz` Hz.
    pub fn check(&self, channels: usize, fs_hz: f64) -> Result<(), String> {
        if channels != self.channels {
            return Err(format!(
                "{} declares {} capture channel(s); the source gives {channels}",
                self.by, self.channels
            ));
        }
        if (fs_hz - self.fs_hz).abs() > 1e-6 * self.fs_hz {
            return Err(format!(
                "{} captures at {} Hz; the source is at {fs_hz} Hz",
                self.by, self.fs_hz
            ));
        }
        Ok(())
    }
}
