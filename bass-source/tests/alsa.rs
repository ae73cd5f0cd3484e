//! ALSA capture without hardware: the test writes an ALSA configuration (pointed to by
//! `ALSA_CONFIG_PATH`) whose PCM `afetest` is a `file` plugin reading a raw file of known
//! samples over a `null` slave, so that capturing from it returns the file's frames;
//! `afe44k` puts a `rate` plugin (4000..=768000 Hz) in front of it.
#![cfg(feature = "alsa")]

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use afe_bass_source::{
    list_devices, AlsaConfig, AlsaSource, Error, Feeder, PortFormat, Reader, Source,
};

const FRAMES: usize = 4410;

/// Frame `t` of the raw file: left and right encode the index.
fn frame(t: usize) -> [i32; 2] {
    let t = t as i32;
    [t.wrapping_mul(48_271), -t.wrapping_mul(9_973)]
}

/// Writes the raw file and the configuration once, and points ALSA at it.
fn setup() {
    static DONE: OnceLock<PathBuf> = OnceLock::new();
    DONE.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("afe-alsa-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let raw = dir.join("in.raw");
        let bytes: Vec<u8> = (0..FRAMES)
            .flat_map(frame)
            .flat_map(i32::to_ne_bytes)
            .collect();
        std::fs::write(&raw, bytes).expect("raw file");
        let conf = dir.join("asound.conf");
        std::fs::write(
            &conf,
            format!(
                "pcm.afetest {{\n  type file\n  slave.pcm {{ type null }}\n  file \"/dev/null\"\n  \
                 infile \"{}\"\n  format \"raw\"\n  hint {{ show on description \"afe test capture\" }}\n}}\n\
                 pcm.afe44k {{\n  type rate\n  slave {{ pcm \"afetest\" rate 44100 }}\n}}\n",
                raw.display()
            ),
        )
        .expect("asound.conf");
        std::env::set_var("ALSA_CONFIG_PATH", &conf);
        conf
    });
}

fn config(frames_per_chunk: usize) -> AlsaConfig {
    AlsaConfig {
        device: "afetest".into(),
        format: PortFormat {
            sample_rate: 44100,
            channels: 2,
            frames_per_chunk,
            chunks_on_port: 4,
        },
    }
}

#[test]
fn defaults_are_bass_defaults() {
    let c = AlsaConfig::default();
    assert_eq!(c.device, "hw:1,0");
    assert_eq!(
        (
            c.format.sample_rate,
            c.format.frames_per_chunk,
            c.format.chunks_on_port
        ),
        (44100, 2205, 20)
    );
}

#[test]
fn capture_returns_the_frames_of_the_file_through_the_port() {
    setup();
    let source = AlsaSource::acquire(&config(441)).expect("acquire afetest");
    let mut feeder = Feeder::new(source, Some(FRAMES as u64)).expect("feeder");
    let mut reader = Reader::new(feeder.port(), 0);
    let (mut l, mut r) = (vec![0; 1000], vec![0; 1000]);
    let mut got = Vec::new();
    while !reader.at_end() {
        let fetch = reader.read(&mut [&mut l, &mut r]).expect("read");
        assert_eq!(fetch.lost, 0);
        got.extend((0..fetch.frames).map(|i| [l[i], r[i]]));
        if fetch.frames == 0 {
            feeder.pump().expect("capture");
        }
    }
    assert_eq!(got.len(), FRAMES);
    for (t, f) in got.iter().enumerate() {
        assert_eq!(*f, frame(t), "frame {t}");
    }
    assert_eq!(feeder.port().n_frames_per_chunk(), 441);
    assert_eq!(feeder.source().overruns(), 0);
}

#[test]
fn chunks_are_periods_and_stop_stops() {
    setup();
    let mut source = AlsaSource::acquire(&config(100)).expect("acquire afetest");
    let mut out = vec![Vec::new(), Vec::new()];
    assert_eq!(source.read_chunk(&mut out, 1000).expect("read"), 100);
    assert_eq!([out[0][7], out[1][7]], frame(7));
    assert_eq!(source.read_chunk(&mut out, 30).expect("read"), 30);
    assert_eq!([out[0][0], out[1][0]], frame(100));
    source.stop().expect("stop");
}

#[test]
fn devices_list_the_configured_capture_pcm() {
    setup();
    let devices = list_devices().expect("list");
    let dev = devices
        .iter()
        .find(|d| d.name == "afetest")
        .unwrap_or_else(|| panic!("afetest not in {devices:?}"));
    assert_eq!(dev.description, "afe test capture");
}

#[test]
fn a_missing_device_and_an_unsupported_rate_are_clear_errors() {
    setup();
    let mut c = config(441);
    c.device = "nosuchdevice".into();
    let err = AlsaSource::acquire(&c).expect_err("missing device");
    assert!(matches!(err, Error::DeviceNotFound { .. }), "{err:?}");
    assert!(err.to_string().contains("'nosuchdevice'"), "{err}");
    assert!(err.to_string().contains("afe devices"), "{err}");

    let mut c = config(441);
    c.device = "afe44k".into();
    c.format.sample_rate = 1;
    let err = AlsaSource::acquire(&c).expect_err("1 Hz");
    let Error::UnsupportedRate { rate, min, max, .. } = &err else {
        panic!("{err:?}");
    };
    assert_eq!(*rate, 1);
    assert!(*min > 1 && *max >= 44100, "{err}");
    assert!(err.to_string().contains("cannot capture at 1 Hz"), "{err}");
}
