//! ALSA capture (cargo feature `alsa`): BASS's `ListDevices`, `Acquire` and `Stop`.

use alsa::pcm::{Access, Format, HwParams, PCM};
use alsa::{Direction, ValueOr};

use crate::error::{Error, Result};
use crate::port::PortFormat;
use crate::source::{Clock, Source};

/// A PCM device that can capture.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaptureDevice {
    /// The ALSA device name to acquire from, e.g. `hw:1,0` or `default`.
    pub name: String,
    /// What ALSA says about it (card and device names, or the configuration's hint).
    pub description: String,
}

/// BASS's `ListDevices`: the capture devices of every sound card (`hw:CARD,DEVICE`),
/// then the capture-capable PCMs that the ALSA configuration advertises (`default`,
/// plugins with a `hint`).
pub fn list_devices() -> Result<Vec<CaptureDevice>> {
    let mut devices = Vec::new();
    for card in alsa::card::Iter::new().flatten() {
        let Ok(ctl) = alsa::ctl::Ctl::from_card(&card, false) else {
            continue;
        };
        let card_name = card.get_name().unwrap_or_default();
        for dev in alsa::ctl::DeviceIter::new(&ctl) {
            let Ok(dev) = u32::try_from(dev) else {
                continue;
            };
            if let Ok(info) = ctl.pcm_info(dev, 0, Direction::Capture) {
                devices.push(CaptureDevice {
                    name: format!("hw:{},{dev}", card.get_index()),
                    description: format!("{card_name}: {}", info.get_name().unwrap_or_default()),
                });
            }
        }
    }
    let hints = alsa::device_name::HintIter::new_str(None, "pcm").map_err(|e| Error::Alsa {
        device: "(configuration)".into(),
        reason: format!("cannot list the configured PCMs: {e}"),
    })?;
    for hint in hints {
        let (Some(name), Some(Direction::Capture) | None) = (hint.name, hint.direction) else {
            continue;
        };
        if devices.iter().all(|d| d.name != name) {
            let description = hint.desc.unwrap_or_default().replace('\n', " ");
            devices.push(CaptureDevice { name, description });
        }
    }
    Ok(devices)
}

/// What to acquire: BASS's `Acquire` arguments.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AlsaConfig {
    /// ALSA device name.
    pub device: String,
    /// Sampling rate (Hz), channels, frames per chunk (the ALSA period) and chunks on the port.
    pub format: PortFormat,
}

impl Default for AlsaConfig {
    /// BASS's defaults: `hw:1,0`, 44100 Hz, 2 channels, 2205 frames per chunk, 20 chunks.
    fn default() -> Self {
        AlsaConfig {
            device: "hw:1,0".into(),
            format: PortFormat::default(),
        }
    }
}

/// Capture from an ALSA device as BASS does: interleaved signed 32-bit samples, one ALSA
/// period per chunk. Reading blocks until the device has captured the chunk.
pub struct AlsaSource {
    config: AlsaConfig,
    pcm: PCM,
    interleaved: Vec<i32>,
    overruns: u64,
}

impl std::fmt::Debug for AlsaSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AlsaSource")
            .field("config", &self.config)
            .field("overruns", &self.overruns)
            .finish_non_exhaustive()
    }
}

impl AlsaSource {
    /// BASS's `Acquire`: opens `config.device` for capture at `config.format` and starts
    /// it. Fails with [`Error::DeviceNotFound`] for a device that cannot be opened and
    /// [`Error::UnsupportedRate`] for a rate the device does not take.
    pub fn acquire(config: &AlsaConfig) -> Result<Self> {
        let device = config.device.clone();
        let format = config.format;
        format.check()?;
        let fail = |reason: String| Error::Alsa {
            device: device.clone(),
            reason,
        };
        // alsa-lib's own messages go to a buffer (and into the error) instead of stderr.
        let said = alsa::Output::local_error_handler().ok();
        let pcm = PCM::new(&device, Direction::Capture, false).map_err(|e| {
            let os = std::io::Error::from_raw_os_error(e.errno()).to_string();
            let said = said
                .as_ref()
                .map(|o| o.borrow().to_string())
                .unwrap_or_default();
            Error::DeviceNotFound {
                device: device.clone(),
                reason: match said.lines().last().and_then(|l| l.split_once(": ")) {
                    Some((_, message)) => format!("{message} ({os})"),
                    None => os,
                },
            }
        })?;
        {
            let hw = HwParams::any(&pcm).map_err(|e| fail(e.to_string()))?;
            hw.set_access(Access::RWInterleaved)
                .map_err(|e| fail(format!("no interleaved capture ({e})")))?;
            hw.set_format(Format::s32()).map_err(|e| {
                fail(format!(
                    "does not capture signed 32-bit samples ({e}); `plug:{device}` converts"
                ))
            })?;
            let channels = u32::try_from(format.channels).unwrap_or(u32::MAX);
            hw.set_channels(channels).map_err(|e| {
                fail(format!(
                    "does not capture {channels} channel(s) ({e}); it takes {}..={}",
                    hw.get_channels_min().unwrap_or(0),
                    hw.get_channels_max().unwrap_or(0)
                ))
            })?;
            if hw.test_rate(format.sample_rate).is_err() {
                return Err(Error::UnsupportedRate {
                    device: device.clone(),
                    rate: format.sample_rate,
                    min: hw.get_rate_min().unwrap_or(0),
                    max: hw.get_rate_max().unwrap_or(0),
                });
            }
            hw.set_rate(format.sample_rate, ValueOr::Nearest)
                .map_err(|e| fail(e.to_string()))?;
            let period = alsa::pcm::Frames::try_from(format.frames_per_chunk)
                .map_err(|_| fail("nFramesPerChunk is too large".into()))?;
            let period = hw
                .set_period_size_near(period, ValueOr::Nearest)
                .map_err(|e| fail(format!("cannot set the period: {e}")))?;
            hw.set_buffer_size_near(period.saturating_mul(4))
                .map_err(|e| fail(format!("cannot set the buffer: {e}")))?;
            pcm.hw_params(&hw)
                .map_err(|e| fail(format!("refuses the capture configuration: {e}")))?;
        }
        pcm.start()
            .map_err(|e| fail(format!("cannot start: {e}")))?;
        Ok(AlsaSource {
            interleaved: vec![0; format.frames_per_chunk * format.channels],
            config: config.clone(),
            pcm,
            overruns: 0,
        })
    }

    /// BASS's `Stop`: stops the capture and drops what the device still holds.
    pub fn stop(self) -> Result<()> {
        self.pcm.drop().map_err(|e| Error::Alsa {
            device: self.config.device.clone(),
            reason: format!("cannot stop: {e}"),
        })
    }
}

impl Source for AlsaSource {
    type Sample = i32;

    fn format(&self) -> PortFormat {
        self.config.format
    }

    fn clock(&self) -> Clock {
        Clock::Device
    }

    fn read_chunk(&mut self, out: &mut [Vec<i32>], max_frames: usize) -> Result<usize> {
        let nch = self.config.format.channels;
        if out.len() != nch {
            return Err(Error::ChannelCount {
                expected: nch,
                actual: out.len(),
            });
        }
        let want = max_frames.min(self.config.format.frames_per_chunk);
        let fail = |reason: String| Error::Alsa {
            device: self.config.device.clone(),
            reason,
        };
        let io = self
            .pcm
            .io_i32()
            .map_err(|e| fail(format!("cannot read: {e}")))?;
        let mut got = 0;
        while got < want {
            match io.readi(&mut self.interleaved[got * nch..want * nch]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.errno() == libc::EPIPE => {
                    self.overruns += 1;
                    self.pcm
                        .try_recover(e, true)
                        .map_err(|e| fail(format!("cannot recover from an overrun: {e}")))?;
                }
                Err(e) => return Err(fail(format!("capture failed: {e}"))),
            }
        }
        for (c, o) in out.iter_mut().enumerate() {
            o.clear();
            o.extend(self.interleaved[..got * nch].iter().skip(c).step_by(nch));
        }
        Ok(got)
    }

    fn overruns(&self) -> u64 {
        self.overruns
    }
}
