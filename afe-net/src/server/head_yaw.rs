//! The head's yaw as the robot's motor controller publishes it on `afe/<name>/head/yaw`:
//! each sample one JSON object `{"t_s": s of the stream, "yaw_deg": deg, positive to the
//! left}`, fed to the stream's head pose for the `tracking` request. A sample that is not
//! such an object, goes back in time or leaves the neck's range is refused and counted,
//! and said on stderr (the first, then every [`WARN_EVERY`]th); none stops the stream.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use afe::HeadPose;
use serde::Deserialize;
use zenoh::pubsub::Subscriber;
use zenoh::{Session, Wait};

use crate::RemoteError;

/// A refused sample is said on stderr once per this many.
const WARN_EVERY: u64 = 1000;

/// Largest sample read, bytes: a point is some 40.
const MAX_SAMPLE_BYTES: usize = 256;

/// One reported yaw.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Point {
    t_s: f64,
    yaw_deg: f64,
}

/// Samples taken and refused, shared with the subscriber's callback.
#[derive(Debug, Default)]
pub(crate) struct YawCounts {
    pub taken: AtomicU64,
    pub refused: AtomicU64,
}

/// Subscribes `key` into `pose`, refusing yaws outside `range_deg` (lowest, highest).
pub(crate) fn subscribe(
    session: &Session,
    key: String,
    pose: HeadPose,
    range_deg: Option<(f64, f64)>,
) -> Result<(Subscriber<()>, Arc<YawCounts>), RemoteError> {
    let counts = Arc::new(YawCounts::default());
    let counted = counts.clone();
    let shown = key.clone();
    let subscriber = session
        .declare_subscriber(key)
        .callback(move |sample| {
            let bytes = sample.payload().to_bytes();
            match take(&bytes, &pose, range_deg) {
                Ok(()) => {
                    counted.taken.fetch_add(1, Ordering::Relaxed);
                }
                Err(why) => {
                    let n = counted.refused.fetch_add(1, Ordering::Relaxed);
                    if n % WARN_EVERY == 0 {
                        eprintln!("afe serve: {shown}: refused ({} so far): {why}", n + 1);
                    }
                }
            }
        })
        .wait()?;
    Ok((subscriber, counts))
}

/// Feeds one sample's point to `pose`, or says why not.
fn take(bytes: &[u8], pose: &HeadPose, range_deg: Option<(f64, f64)>) -> Result<(), String> {
    if bytes.len() > MAX_SAMPLE_BYTES {
        return Err(format!(
            "a sample of {} bytes: a point is {{\"t_s\": s, \"yaw_deg\": deg}}",
            bytes.len()
        ));
    }
    let p: Point = serde_json::from_slice(bytes)
        .map_err(|e| format!("not {{\"t_s\": s, \"yaw_deg\": deg}}: {e}"))?;
    if let Some((lo, hi)) = range_deg {
        if !(lo..=hi).contains(&p.yaw_deg) {
            return Err(format!(
                "the yaw {} deg at t_s = {} is beyond the neck's {lo} to {hi} deg",
                p.yaw_deg, p.t_s
            ));
        }
    }
    pose.push(p.t_s, p.yaw_deg).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_taken_or_refused_with_the_reason() {
        let pose = HeadPose::new();
        let range = Some((-95.0, 95.0));
        take(br#"{"t_s": 0.5, "yaw_deg": 20}"#, &pose, range).expect("a point");
        assert_eq!(pose.yaw_at(1.0), 20.0);
        let e = |b: &[u8]| take(b, &pose, range).expect_err("refused");
        assert!(e(b"20").starts_with("not {\"t_s\": s"), "{}", e(b"20"));
        assert!(e(br#"{"t_s": 1, "yaw_deg": 2, "x": 3}"#).contains("unknown field"));
        assert!(e(br#"{"t_s": 0.4, "yaw_deg": 2}"#).contains("times must increase"));
        assert!(e(br#"{"t_s": 2, "yaw_deg": 120}"#).contains("beyond the neck's -95 to 95"));
        assert!(e(&[b' '; 300]).contains("300 bytes"));
        assert_eq!(pose.len(), 1, "nothing refused was fed");
    }
}
