//! The robot's body as a file (a platform descriptor, as the BABEL robot platform
//! descriptions are): the robot's name, its body parts and joints, and its audio device:
//! which capture channel is which microphone, where on which part, and the head model
//! that hears. `afe serve --platform` checks it against the source and publishes it, so
//! that a client asks the robot what it is; `afe locate` takes its ears and head from it.
//! The schema is documented in `docs/platform.md`; this is version 1.

use std::collections::HashSet;
use std::path::Path;

use serde::{Deserialize, Serialize};

use afe_core::ExpectedSource;

use crate::{Head, HeadYaw, SpatialError};

/// The schema version this build reads.
pub const PLATFORM_VERSION: u32 = 1;

/// How far a yaw track may go beyond the neck's limits, deg: a controller's overshoot.
pub const YAW_LIMIT_SLACK_DEG: f64 = 5.0;

/// A robot's body and its microphones (schema version 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Platform {
    /// The schema version: [`PLATFORM_VERSION`].
    pub version: u32,
    /// The robot's name.
    pub robot: String,
    /// Its rigid parts, the root (no parent: the base) first.
    pub parts: Vec<BodyPart>,
    /// The joints between parts.
    #[serde(default)]
    pub joints: Vec<Joint>,
    /// The capture device.
    pub audio: AudioDevice,
}

/// A rigid part of the body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyPart {
    /// Its name (`base`, `neck`, `head`...), unique.
    pub name: String,
    /// The part it is fixed or jointed to; `None` for the root.
    #[serde(default)]
    pub parent: Option<String>,
    /// Its origin on its parent, m: x forward, y left, z up.
    #[serde(default)]
    pub position_m: [f64; 3],
}

/// What a joint turns about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    /// About the vertical axis, positive to the left (as azimuths are).
    Yaw,
    /// About the left axis, positive downward.
    Pitch,
}

/// A joint that moves one part against its parent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Joint {
    /// Its name (`neck_yaw`...).
    pub name: String,
    /// What it turns about.
    pub kind: JointKind,
    /// The part it moves (whose parent it turns against).
    pub part: String,
    /// Its lowest angle, deg.
    pub min_deg: f64,
    /// Its highest angle, deg.
    pub max_deg: f64,
    /// Its fastest turn, deg/s.
    pub speed_deg_s: f64,
}

/// What a capture channel is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ChannelRole {
    /// The left ear (the binaural pair's first channel).
    LeftEar,
    /// The right ear.
    RightEar,
    /// Another microphone.
    Extra,
}

/// One capture channel's microphone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Microphone {
    /// Its channel in the capture, from 0.
    pub channel: usize,
    /// What it is.
    pub role: ChannelRole,
    /// The part it is fixed to.
    pub part: String,
    /// Where on that part, m: x forward, y left, z up.
    pub position_m: [f64; 3],
    /// Where it points on that part, deg: azimuth (positive to the left) and elevation.
    #[serde(default)]
    pub orientation_deg: [f64; 2],
}

/// The capture device and the head that hears.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AudioDevice {
    /// Its sampling rate, Hz.
    pub sample_rate_hz: f64,
    /// The head model, as `afe locate --head` takes it: `kemar`,
    /// `sphere:radius=M[,ears=DEG]`, or a SOFA file (relative to the descriptor's
    /// folder).
    pub head: String,
    /// Each capture channel, channels 0 to N − 1 once each.
    pub channels: Vec<Microphone>,
}

impl Platform {
    /// The descriptor in the JSON `text`, checked (see [`Platform::check`]); a SOFA head
    /// named relative is resolved against `folder` (the descriptor's).
    pub fn parse(text: &str, folder: &Path) -> Result<Platform, SpatialError> {
        let mut p: Platform = serde_json::from_str(text)
            .map_err(|e| SpatialError::Platform(format!("not a platform descriptor: {e}")))?;
        if is_sofa_path(&p.audio.head) && Path::new(&p.audio.head).is_relative() {
            p.audio.head = folder.join(&p.audio.head).display().to_string();
        }
        p.check()?;
        Ok(p)
    }

    /// Checks what the types cannot: the version, unique part names with known parents
    /// and one root, joints on known parts with `min < max` and a positive speed, a
    /// positive rate, channels 0 to N − 1 once each on known parts with one left ear and
    /// one right ear, finite positions, and a head file that exists.
    pub fn check(&self) -> Result<(), SpatialError> {
        let bad = |why: String| Err(SpatialError::Platform(format!("'{}': {why}", self.robot)));
        if self.version != PLATFORM_VERSION {
            return bad(format!(
                "schema version {} (this build reads version {PLATFORM_VERSION})",
                self.version
            ));
        }
        let mut names = HashSet::new();
        for part in &self.parts {
            if !names.insert(part.name.as_str()) {
                return bad(format!("two parts are named '{}'", part.name));
            }
            if !part.position_m.iter().all(|v| v.is_finite()) {
                return bad(format!(
                    "part '{}' has a position that is not finite",
                    part.name
                ));
            }
        }
        let roots = self.parts.iter().filter(|p| p.parent.is_none()).count();
        if roots != 1 {
            return bad(format!(
                "{roots} parts without a parent: one, the base, is the root"
            ));
        }
        let known = |name: &str| names.contains(name);
        for part in &self.parts {
            if let Some(parent) = part.parent.as_deref().filter(|p| !known(p)) {
                return bad(format!("part '{}' hangs on '{parent}', no part", part.name));
            }
        }
        for j in &self.joints {
            if !known(&j.part) {
                return bad(format!("joint '{}' moves '{}', no part", j.name, j.part));
            }
            if !(j.min_deg.is_finite() && j.max_deg.is_finite() && j.min_deg < j.max_deg) {
                return bad(format!(
                    "joint '{}' has limits {}..{} deg: the lower must be below the upper",
                    j.name, j.min_deg, j.max_deg
                ));
            }
            if !(j.speed_deg_s.is_finite() && j.speed_deg_s > 0.0) {
                return bad(format!(
                    "joint '{}' turns at {} deg/s: a positive speed",
                    j.name, j.speed_deg_s
                ));
            }
        }
        let a = &self.audio;
        if !(a.sample_rate_hz.is_finite() && a.sample_rate_hz > 0.0) {
            return bad(format!("a sampling rate of {} Hz", a.sample_rate_hz));
        }
        let n = a.channels.len();
        let mut seen = vec![false; n];
        for m in &a.channels {
            match seen.get_mut(m.channel) {
                Some(s) if !*s => *s = true,
                Some(_) => return bad(format!("channel {} is declared twice", m.channel)),
                None => {
                    return bad(format!(
                        "channel {} of {n}: channels are numbered 0 to {}",
                        m.channel,
                        n.saturating_sub(1)
                    ))
                }
            }
            if !known(&m.part) {
                return bad(format!("channel {} is on '{}', no part", m.channel, m.part));
            }
            if !(m.position_m.iter().chain(&m.orientation_deg)).all(|v| v.is_finite()) {
                return bad(format!(
                    "channel {} has a pose that is not finite",
                    m.channel
                ));
            }
        }
        for role in [ChannelRole::LeftEar, ChannelRole::RightEar] {
            let count = a.channels.iter().filter(|m| m.role == role).count();
            if count != 1 {
                return bad(format!(
                    "{count} channels are the {}: a binaural head has one",
                    role_name(role)
                ));
            }
        }
        if is_sofa_path(&a.head) && !Path::new(&a.head).is_file() {
            return bad(format!("its head file {} does not exist", a.head));
        }
        Ok(())
    }

    /// What its capture device gives: a source of other channels or another rate is
    /// not this robot's.
    pub fn expected_source(&self) -> ExpectedSource {
        ExpectedSource {
            by: format!("'{}'", self.robot),
            channels: self.audio.channels.len(),
            fs_hz: self.audio.sample_rate_hz,
        }
    }

    /// Checks a source of `channels` channels at `fs_hz` Hz against the descriptor's
    /// capture device.
    pub fn check_source(&self, channels: usize, fs_hz: f64) -> Result<(), SpatialError> {
        self.expected_source()
            .check(channels, fs_hz)
            .map_err(SpatialError::Platform)
    }

    /// The capture channels of the left and the right ear.
    pub fn ears(&self) -> [usize; 2] {
        let channel = |role| {
            self.audio
                .channels
                .iter()
                .find(|m| m.role == role)
                .map_or(0, |m| m.channel)
        };
        [
            channel(ChannelRole::LeftEar),
            channel(ChannelRole::RightEar),
        ]
    }

    /// The head model it names.
    pub fn head(&self) -> Result<Head, SpatialError> {
        Head::parse(&self.audio.head)
    }

    /// The joint that turns the head about the vertical (the first yaw joint), if any.
    pub fn neck_yaw(&self) -> Option<&Joint> {
        self.joints.iter().find(|j| j.kind == JointKind::Yaw)
    }

    /// The yaws a report may give (deg, lowest and highest): the neck's limits widened by
    /// [`YAW_LIMIT_SLACK_DEG`]; only 0 without a yaw joint.
    pub fn yaw_range_deg(&self) -> (f64, f64) {
        self.neck_yaw().map_or((0.0, 0.0), |neck| {
            (
                neck.min_deg - YAW_LIMIT_SLACK_DEG,
                neck.max_deg + YAW_LIMIT_SLACK_DEG,
            )
        })
    }

    /// Checks a yaw track against the neck's limits (within [`YAW_LIMIT_SLACK_DEG`]); a
    /// robot without a yaw joint cannot turn its head at all.
    pub fn check_yaw(&self, track: &HeadYaw) -> Result<(), SpatialError> {
        let Some(neck) = self.neck_yaw() else {
            return Err(SpatialError::Platform(format!(
                "'{}' has no yaw joint: its head cannot turn, so it has no yaw track",
                self.robot
            )));
        };
        let (lo, hi) = self.yaw_range_deg();
        match track
            .points()
            .iter()
            .find(|&&(_, yaw)| !(lo..=hi).contains(&yaw))
        {
            Some((t, yaw)) => Err(SpatialError::Platform(format!(
                "the head yaw {yaw} deg at t_s = {t} is beyond '{}''s joint '{}' \
                 ({} to {} deg)",
                self.robot, neck.name, neck.min_deg, neck.max_deg
            ))),
            None => Ok(()),
        }
    }
}

/// Whether a head spec names a SOFA file (what [`Head::parse`] reads as one).
fn is_sofa_path(spec: &str) -> bool {
    Path::new(spec)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("sofa"))
}

fn role_name(role: ChannelRole) -> &'static str {
    match role {
        ChannelRole::LeftEar => "left ear",
        ChannelRole::RightEar => "right ear",
        ChannelRole::Extra => "extra microphone",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A descriptor shipped in `data/platforms/`.
    fn shipped_text(name: &str) -> String {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../data/platforms")
            .join(name);
        std::fs::read_to_string(path).expect("descriptor")
    }

    fn ball() -> Platform {
        Platform::parse(&shipped_text("ball-15cm.json"), Path::new(".")).expect("valid")
    }

    /// Both shipped descriptors are valid; the ball is the seed robots' (24414 Hz, a
    /// 7.5-cm sphere, ears on channels 0 and 1) and turns its head +-90 deg.
    #[test]
    fn the_shipped_descriptors_are_valid() {
        let b = ball();
        assert_eq!(b.audio.sample_rate_hz, 24414.0);
        assert_eq!(b.ears(), [0, 1]);
        assert!(matches!(b.head().expect("sphere"), Head::Sphere(_)));
        let neck = b.neck_yaw().expect("neck");
        assert_eq!((neck.min_deg, neck.max_deg), (-90.0, 90.0));
        let k =
            Platform::parse(&shipped_text("kemar-pan-unit.json"), Path::new(".")).expect("valid");
        assert_eq!(k.audio.head, "kemar");
        assert_eq!(k.audio.sample_rate_hz, 44100.0);
        // a round trip through its serde form keeps it
        let text = serde_json::to_string(&k).expect("json");
        assert_eq!(Platform::parse(&text, Path::new(".")).expect("again"), k);
    }

    /// A source of another channel count or rate is refused, naming both.
    #[test]
    fn a_source_that_does_not_match_is_refused() {
        let b = ball();
        b.check_source(2, 24414.0).expect("matches");
        let e = b
            .check_source(3, 24414.0)
            .expect_err("channels")
            .to_string();
        assert!(
            e.contains("declares 2 capture channel(s); the source gives 3"),
            "{e}"
        );
        let e = b.check_source(2, 44100.0).expect_err("rate").to_string();
        assert!(
            e.contains("captures at 24414 Hz; the source is at 44100 Hz"),
            "{e}"
        );
    }

    /// Each kind of bad descriptor is one clear error naming what is wrong.
    #[test]
    fn bad_descriptors_are_clear_errors() {
        let good: serde_json::Value =
            serde_json::from_str(&shipped_text("ball-15cm.json")).expect("json");
        let with = |edit: &dyn Fn(&mut serde_json::Value)| {
            let mut v = good.clone();
            edit(&mut v);
            Platform::parse(&v.to_string(), Path::new("/nonexistent"))
                .expect_err("refused")
                .to_string()
        };
        type Edit = Box<dyn Fn(&mut serde_json::Value)>;
        let cases: Vec<(&str, Edit)> = vec![
            ("schema version 2", Box::new(|v| v["version"] = 2.into())),
            (
                "unknown field `colour`",
                Box::new(|v| v["colour"] = "red".into()),
            ),
            (
                "channel 0 is declared twice",
                Box::new(|v| v["audio"]["channels"][1]["channel"] = 0.into()),
            ),
            (
                "0 channels are the right ear",
                Box::new(|v| v["audio"]["channels"][1]["role"] = "extra".into()),
            ),
            (
                "channel 5 of 2",
                Box::new(|v| v["audio"]["channels"][1]["channel"] = 5.into()),
            ),
            (
                "is on 'arm', no part",
                Box::new(|v| v["audio"]["channels"][0]["part"] = "arm".into()),
            ),
            (
                "limits 90..-90 deg",
                Box::new(|v| {
                    v["joints"][0]["min_deg"] = 90.into();
                    v["joints"][0]["max_deg"] = (-90).into();
                }),
            ),
            (
                "its head file /nonexistent/head.sofa does not exist",
                Box::new(|v| v["audio"]["head"] = "head.sofa".into()),
            ),
            (
                "2 parts without a parent",
                Box::new(|v| v["parts"][1]["parent"] = serde_json::Value::Null),
            ),
            (
                "a sampling rate of 0 Hz",
                Box::new(|v| v["audio"]["sample_rate_hz"] = 0.into()),
            ),
        ];
        for (want, edit) in cases {
            let e = with(edit.as_ref());
            assert!(e.contains(want), "{want}: {e}");
        }
        let e = Platform::parse("{", Path::new("."))
            .expect_err("json")
            .to_string();
        assert!(
            e.starts_with("platform: not a platform descriptor: "),
            "{e}"
        );
    }

    /// A yaw track within the neck's limits (and their slack) passes; one far beyond
    /// them, or on a robot without a yaw joint, is refused.
    #[test]
    fn a_yaw_track_is_held_to_the_necks_limits() {
        let b = ball();
        let turn = HeadYaw::new(&[(0.0, 0.0), (1.0, 30.0), (2.0, -93.0)]).expect("track");
        b.check_yaw(&turn).expect("within limits");
        let far = HeadYaw::new(&[(0.0, 0.0), (1.0, 120.0)]).expect("track");
        let e = b.check_yaw(&far).expect_err("beyond").to_string();
        assert!(
            e.contains("the head yaw 120 deg at t_s = 1 is beyond"),
            "{e}"
        );
        let mut fixed = b.clone();
        fixed.joints.clear();
        let e = fixed.check_yaw(&turn).expect_err("no neck").to_string();
        assert!(e.contains("has no yaw joint"), "{e}");
    }
}
