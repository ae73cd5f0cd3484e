//! `afe locate`: where the sources of a binaural WAV file are, for a head model.

use std::path::PathBuf;

use afe_spatial::{locate, track, Head, LocaliserParams, Located, Neck, Tracked, TrackerParams};
use serde_json::json;

use crate::error::CliError;
use crate::files::{read_capture, read_head_yaw, read_input, read_platform};
use crate::outln;

/// `afe locate IN.wav [--head kemar|sphere:radius=M[,ears=DEG]|FILE.sofa | --platform
/// FILE.json] [--sources N] [--head-yaw FILE.csv] [--json]`.
#[derive(clap::Args)]
pub(crate) struct LocateArgs {
    /// Input WAV file, two channels (left ear, right ear).
    input: PathBuf,
    /// The head that heard it: `kemar` (the MIT KEMAR set, from Debian's libmysofa1; the
    /// default), `sphere:radius=M[,ears=DEG]` (a rigid sphere; `sphere` alone: the 15-cm
    /// ball with ears at +-90 deg) or a SimpleFreeFieldHRIR .sofa file.
    #[arg(long, conflicts_with = "platform")]
    head: Option<String>,
    /// The robot that recorded it (a platform descriptor, docs/platform.md): its head,
    /// which channels are its ears, its rate and channel count (checked against the
    /// file) and its neck's limits (checked against --head-yaw).
    #[arg(long, value_name = "FILE.json")]
    platform: Option<PathBuf>,
    /// How many sources to report (default: every one at least 0.9 as salient as the
    /// first).
    #[arg(long, value_name = "N")]
    sources: Option<usize>,
    /// The head's yaw over time: a CSV of rows `t_s,yaw_deg` (yaw positive to the left,
    /// times increasing; a header row of those names may come first). Azimuths are then
    /// in the world (world = relative + yaw), and a turning head tells front from back.
    #[arg(long, value_name = "FILE.csv")]
    head_yaw: Option<PathBuf>,
    /// Track the sources over time (a Bayes filter over world azimuth that carries the
    /// head's turns: a turn tells front from back), reported at 6 Hz: with --json as
    /// "tracked": [{"t_s", "yaw_deg", "tracks": [{"id", "azimuth_deg",
    /// "uncertainty_deg", "mass", "velocity_deg_s", "seen_s", "resolved"}, ...],
    /// "suggested_turn": null or {"turn_deg", "target_yaw_deg", "why": "mirror", "ids"}
    /// or {..., "why": "behind", "id"}}, ...]
    /// (the turn within the platform's neck limits, none without a yaw joint; without a
    /// platform, ±90 deg).
    #[arg(long)]
    track: bool,
    /// Print the sources and the frames as JSON: {"sources": [{"azimuth_deg",
    /// "salience"}, ...], "frames": [{"t_s", "active", "azimuth_deg", "yaw_deg"}, ...],
    /// ...}.
    #[arg(long)]
    json: bool,
}

impl LocateArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        if self.sources == Some(0) {
            return Err("--sources must be at least 1".into());
        }
        let platform = self.platform.as_deref().map(read_platform).transpose()?;
        let head = match (&platform, &self.head) {
            (Some(p), _) => p.head()?,
            (None, Some(spec)) => Head::parse(spec)?,
            (None, None) => Head::parse("kemar")?,
        };
        let yaw = self.head_yaw.as_deref().map(read_head_yaw).transpose()?;
        let audio = match &platform {
            // a robot's capture may hold more than its ears: its descriptor says which
            Some(_) => read_capture(&self.input)?,
            None => read_input(&self.input)?,
        };
        let [left, right] = match &platform {
            Some(p) => {
                p.check_source(audio.channels.len(), audio.fs)?;
                if let Some(track) = &yaw {
                    p.check_yaw(track)?;
                }
                // the channel count checked: each ear is a channel of the file
                p.ears().map(|c| &audio.channels[c])
            }
            None => match audio.channels.as_slice() {
                [left, right] => [left, right],
                _ => {
                    return Err(CliError::Message(format!(
                        "{} has {} channel(s): locating needs two (left ear, right ear)",
                        self.input.display(),
                        audio.channels.len()
                    )))
                }
            },
        };
        let found = locate(
            &head,
            [left, right],
            audio.fs,
            &LocaliserParams::default(),
            self.sources,
            yaw.as_ref(),
        )?;
        let tracked = if self.track {
            let neck = match &platform {
                Some(p) => Neck::of(p).unwrap_or(Neck::STILL),
                None => Neck::default(),
            };
            Some(track(&found, &TrackerParams::default(), &neck)?)
        } else {
            None
        };
        if self.json {
            let mut v = to_json(&head, audio.fs, &found);
            if let Some(tracked) = &tracked {
                v["tracked"] = json!(tracked);
            }
            outln!("{v}");
        } else {
            outln!("{}", table(&head, &found, yaw.is_some()));
            if let Some(last) = tracked.as_ref().and_then(|t| t.last()) {
                outln!("{}", tracks_table(last));
            }
        }
        Ok(())
    }
}

fn to_json(head: &Head, fs_hz: f64, found: &Located) -> serde_json::Value {
    json!({
        "head": head.name(),
        "fs_hz": fs_hz,
        "sources": found.sources.iter().map(|s| json!({
            "azimuth_deg": s.azimuth_deg,
            "salience": s.salience,
        })).collect::<Vec<_>>(),
        "frames": found.frames.iter().map(|f| json!({
            "t_s": f.t_s,
            "active": f.active,
            "azimuth_deg": f.azimuth_deg,
            "yaw_deg": f.yaw_deg,
        })).collect::<Vec<_>>(),
    })
}

/// The sources tracked at the end, in the world.
fn tracks_table(last: &Tracked) -> String {
    let mut lines = vec![format!(
        "{} source(s) tracked at {:.2} s, in the world",
        last.tracks.len(),
        last.t_s
    )];
    lines.push(format!(
        "{:>4} {:>12} {:>15}",
        "id", "azimuth_deg", "uncertainty_deg"
    ));
    for t in &last.tracks {
        lines.push(format!(
            "{:>4} {:>12.1} {:>15.1}",
            t.id, t.azimuth_deg, t.uncertainty_deg
        ));
    }
    lines.join("\n")
}

fn table(head: &Head, found: &Located, world: bool) -> String {
    let active = found.frames.iter().filter(|f| f.active).count();
    let frame = if world {
        "in the world, the head's yaw added"
    } else {
        "relative to the head"
    };
    let mut lines = vec![format!(
        "{} source(s), head {}, {} of {} frames active; azimuth 0 = front, 90 = left, {frame}",
        found.sources.len(),
        head.name(),
        active,
        found.frames.len()
    )];
    lines.push(format!("{:>12} {:>9}", "azimuth_deg", "salience"));
    for s in &found.sources {
        lines.push(format!("{:>12.1} {:>9.3}", s.azimuth_deg, s.salience));
    }
    lines.join("\n")
}
