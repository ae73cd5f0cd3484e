//! Where a frame of sources tracked about a head holds what a view from above draws, as
//! the processor that tracks them describes it (its [`crate::SignalInfo::from_above`]).

use serde::Serialize;

/// Where a frame of sources tracked about a head holds what a view from above draws:
/// `slots` groups of `slot_width` values from the frame's start, each with a source's
/// values at the offsets given (NaN in an empty slot), then the head's values at their
/// indices in the frame. Azimuths in deg, 0 ahead, 90 to the left, in the world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct FromAbove {
    /// Source slots per frame.
    pub slots: usize,
    /// Values per slot.
    pub slot_width: usize,
    /// A source's identity, within its slot.
    pub id: usize,
    /// Its azimuth, deg, within its slot.
    pub azimuth: usize,
    /// Its uncertainty (a spread), deg, within its slot.
    pub uncertainty: usize,
    /// 1 where front was told from back, within its slot.
    pub resolved: usize,
    /// The head's yaw, deg, in the frame.
    pub head_yaw: usize,
    /// The yaw a suggested turn ends at (NaN when none), deg, in the frame.
    pub suggested_yaw: usize,
}
