//! A synthetic source whose head turns (`synth:...,az=DEG,turn=DEG`) reports its yaw to
//! the stream's head pose as it renders, so that the processors that read the pose (the
//! tracking) see the head turn with the audio.

use afe_bass_source::{Clock, Placed, PortFormat, Source, Synth};

use crate::HeadPose;

/// `synth` reporting the yaw of its head to `pose` at the end of every chunk it renders
/// (times in s from its first frame). Writing the pose copies its list of points: on the
/// source's side, never on the processors'.
pub(crate) struct Turning {
    synth: Synth,
    placed: Placed,
    pose: HeadPose,
    frames: u64,
}

impl Turning {
    /// `synth` turning as `placed` says, reported to `pose`, which it starts at yaw 0.
    pub(crate) fn new(
        synth: Synth,
        placed: Placed,
        pose: HeadPose,
    ) -> Result<Self, afe_bass_source::Error> {
        let turning = Turning {
            synth,
            placed,
            pose,
            frames: 0,
        };
        turning.report(0.0)?;
        Ok(turning)
    }

    fn report(&self, t_s: f64) -> Result<(), afe_bass_source::Error> {
        self.pose
            .push(t_s, self.placed.yaw_deg_at(t_s))
            .map_err(|e| afe_bass_source::Error::SynthSpec {
                spec: format!("turn={}", self.placed.turn_deg),
                reason: format!(
                    "the synthetic head reports its own yaw, and another feed reported it too ({e})"
                ),
            })
    }
}

impl Source for Turning {
    type Sample = f64;

    fn format(&self) -> PortFormat {
        self.synth.format()
    }

    fn clock(&self) -> Clock {
        self.synth.clock()
    }

    fn read_chunk(
        &mut self,
        out: &mut [Vec<f64>],
        max_frames: usize,
    ) -> afe_bass_source::Result<usize> {
        let n = self.synth.read_chunk(out, max_frames)?;
        if n > 0 {
            self.frames += n as u64;
            self.report(self.frames as f64 / f64::from(self.synth.spec().fs))?;
        }
        Ok(n)
    }
}
