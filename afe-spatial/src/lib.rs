//! Where a sound is, for a binaural head: head models (measured SOFA sets, the rigid
//! sphere) and a localiser that projects the binaural spectrum on the head's transfer
//! functions (training-free, as binauloc's Stage A).

pub mod head;
pub mod locate;
mod peak;
pub mod platform;
pub mod sofa;
pub mod sphere;
pub mod track;
pub mod tracked;
pub mod turn;
pub mod yaw;

pub use head::Head;
pub use locate::{locate, Localiser, LocaliserParams, Located, Scored, Source};
pub use platform::Platform;
pub use track::{Track, Tracker, TrackerParams};
pub use tracked::{track, Tracked};
pub use turn::{suggest, Neck, Suggestion};
pub use yaw::HeadYaw;

use thiserror::Error;

/// `azimuth_deg` brought into [0, 360): `rem_euclid` alone gives 360 for a tiny
/// negative angle, which rounds up to it.
pub fn wrap_deg(azimuth_deg: f64) -> f64 {
    let a = azimuth_deg.rem_euclid(360.0);
    if a >= 360.0 {
        0.0
    } else {
        a
    }
}

pub(crate) use afe_core::head_pose::turn_deg;

/// What went wrong with a head or a localisation.
#[derive(Debug, Error)]
pub enum SpatialError {
    /// The KEMAR set is not installed where it is looked for.
    #[error(
        "the KEMAR head needs {0} (Debian: apt install libmysofa1; or set AFE_KEMAR_SOFA to \
         the MIT_KEMAR_normal_pinna.sofa file)"
    )]
    NoKemar(String),
    /// A name that is no head.
    #[error(
        "unknown head '{0}': use kemar, sphere:radius=M[,ears=DEG][,distance=M] or the path \
         of a .sofa file"
    )]
    UnknownHead(String),
    /// A sphere parameter out of its range.
    #[error(
        "bad sphere parameter '{0}': radius=M (0.01 to 1 m), ears=DEG (0 to 180), \
         distance=M (beyond the radius)"
    )]
    BadSphere(String),
    /// A SOFA file that cannot serve as a head.
    #[error("head file {path}: {why}")]
    Sofa {
        /// The file.
        path: String,
        /// Why not.
        why: String,
    },
    /// A signal whose rate the head has no responses for.
    #[error(
        "the head {head} has responses up to {max_hz} Hz, below the {fs_hz}-Hz signal's \
         Nyquist frequency"
    )]
    RateAboveHead {
        /// The head's name.
        head: String,
        /// The signal's rate, Hz.
        fs_hz: f64,
        /// The head's highest frequency, Hz.
        max_hz: f64,
    },
    /// Bad localiser input or parameters.
    #[error("{0}")]
    Invalid(String),
    /// A platform descriptor that is not valid, or does not match the source.
    #[error("platform: {0}")]
    Platform(String),
}

#[cfg(test)]
mod tests {
    #[test]
    fn azimuths_wrap_into_0_to_360() {
        assert_eq!(super::wrap_deg(-1e-15), 0.0);
        assert_eq!(super::wrap_deg(-90.0), 270.0);
        assert_eq!(super::wrap_deg(720.5), 0.5);
    }
}
