//! `afe locate` on renders the test makes itself: a talker (the example file's left ear)
//! through the MIT KEMAR set (Debian's libmysofa1, which `.ci/run` installs) at every 30
//! degrees, and through the 15-cm sphere; each found within 5 degrees of the truth, front
//! from back folded for the sphere (it has no pinnae), and how often KEMAR's pinnae tell
//! them apart counted; two talkers on KEMAR; and both heads turning, their yaw track
//! telling front from back.

use std::path::{Path, PathBuf};

use afe_spatial::locate::lateral_deg;
use afe_spatial::Head;
use serde_json::Value;

use crate::common::{afe, assert_clear_error, tmp};

/// The example file's left ear: a second of speech at 44.1 kHz.
fn talker() -> (Vec<f64>, u32) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/example_binaural.wav");
    let mut reader = hound::WavReader::open(path).expect("example file");
    let spec = reader.spec();
    let scale = f64::from(1u32 << (spec.bits_per_sample - 1));
    let samples: Vec<i32> = reader
        .samples::<i32>()
        .map(|s| s.expect("sample"))
        .collect();
    let left = samples
        .chunks(usize::from(spec.channels))
        .map(|f| f64::from(f[0]) / scale)
        .collect();
    (left, spec.sample_rate)
}

fn write_binaural(path: &Path, [l, r]: &[Vec<f64>; 2], fs: u32) {
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: fs,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).expect("wav");
    for (a, b) in l.iter().zip(r) {
        w.write_sample(*a as f32).expect("sample");
        w.write_sample(*b as f32).expect("sample");
    }
    w.finalize().expect("finalize");
}

/// The signed gap from `truth` to `found`, deg in (−180, 180].
fn gap(found: f64, truth: f64) -> f64 {
    180.0 - (180.0 - (found - truth)).rem_euclid(360.0)
}

/// `afe locate --json` of `ears` at `fs` through `head`: the first source's azimuth.
fn located(name: &str, ears: &[Vec<f64>; 2], fs: u32, head: &str) -> f64 {
    located_with(name, ears, fs, &["--head", head])
}

/// What `afe locate --json` with `options` prints for `ears` at `fs` (written to a WAV
/// file named after `name`).
fn locate_json(name: &str, ears: &[Vec<f64>; 2], fs: u32, options: &[&str]) -> Value {
    let wav = tmp(&format!("locate-{name}.wav"));
    write_binaural(&wav, ears, fs);
    let mut args = vec!["locate", wav.to_str().expect("path"), "--json"];
    args.extend_from_slice(options);
    let out = afe(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("json")
}

/// `afe locate --json` of `ears` at `fs` with `options`: every source's azimuth, the most
/// salient first.
fn sources_located(name: &str, ears: &[Vec<f64>; 2], fs: u32, options: &[&str]) -> Vec<f64> {
    let v = locate_json(name, ears, fs, options);
    v["sources"]
        .as_array()
        .expect("sources")
        .iter()
        .map(|s| s["azimuth_deg"].as_f64().expect("azimuth"))
        .collect()
}

/// Two renders heard together: each ear's sum.
fn together([al, ar]: [Vec<f64>; 2], [bl, br]: [Vec<f64>; 2]) -> [Vec<f64>; 2] {
    let sum = |x: Vec<f64>, y: Vec<f64>| x.iter().zip(&y).map(|(p, q)| p + q).collect();
    [sum(al, bl), sum(ar, br)]
}

/// `afe locate --json` of `ears` at `fs` with `options`: the first source's azimuth.
fn located_with(name: &str, ears: &[Vec<f64>; 2], fs: u32, options: &[&str]) -> f64 {
    let v = locate_json(name, ears, fs, options);
    let first = &v["sources"][0];
    let az = first["azimuth_deg"].as_f64().expect("azimuth");
    assert!((0.0..360.0).contains(&az), "{v}");
    assert!(first["salience"].as_f64().is_some_and(|s| s > 0.0), "{v}");
    assert!(v["frames"].as_array().is_some_and(|f| !f.is_empty()), "{v}");
    az
}

#[test]
fn a_talker_on_kemar_is_found_within_5_degrees_at_every_30() {
    let head = Head::parse("kemar").unwrap_or_else(|e| panic!("{e}"));
    let (x, fs) = talker();
    let mut front_back_right = 0;
    for az in (0..360).step_by(30).map(f64::from) {
        let ears = head.render(az, &x, f64::from(fs)).expect("render");
        let found = located(&format!("kemar-{az}"), &ears, fs, "kemar");
        let folded = (lateral_deg(found) - lateral_deg(az)).abs();
        assert!(folded <= 5.0, "{az} deg: found {found}");
        if gap(found, az).abs() <= 5.0 {
            front_back_right += 1;
        }
    }
    eprintln!("KEMAR's pinnae told front from back for {front_back_right} of 12 azimuths");
}

#[test]
fn a_talker_on_the_sphere_is_found_within_5_degrees_folded_off_the_grid() {
    let head = Head::parse("sphere").expect("sphere");
    let (x, fs) = talker();
    for az in [7.0, 33.5, 61.0, 118.0, 200.0, 284.5] {
        let ears = head.render(az, &x, f64::from(fs)).expect("render");
        let found = located(&format!("sphere-{az}"), &ears, fs, "sphere");
        let folded = (lateral_deg(found) - lateral_deg(az)).abs();
        assert!(folded <= 5.0, "{az} deg: found {found}");
    }
}

/// `x` from `world_deg` as `head` hears it while turning by `yaw(t)` deg.
fn turning_render(
    head: &Head,
    world_deg: f64,
    yaw: impl Fn(f64) -> f64,
    x: &[f64],
    fs: u32,
) -> [Vec<f64>; 2] {
    moving_render(head, |t| world_deg - yaw(t), x, fs)
}

/// `x` as `head` hears it from the head-relative `azimuth(t)` deg: 50-ms Hann windows at
/// half overlap (they add up to 1), each rendered from the azimuth at its centre.
fn moving_render(head: &Head, azimuth: impl Fn(f64) -> f64, x: &[f64], fs: u32) -> [Vec<f64>; 2] {
    let hop = fs as usize / 40;
    let window: Vec<f64> = (0..2 * hop)
        .map(|k| 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / hop as f64).cos())
        .collect();
    let mut ears = [vec![0.0; x.len()], vec![0.0; x.len()]];
    for start in (0..x.len()).step_by(hop).map(|s| s as isize - hop as isize) {
        let at = |k: usize| start + k as isize;
        let piece: Vec<f64> = (0..2 * hop)
            .map(|k| {
                usize::try_from(at(k))
                    .ok()
                    .and_then(|t| x.get(t))
                    .map_or(0.0, |v| v * window[k])
            })
            .collect();
        let centre = (start + hop as isize) as f64 / f64::from(fs);
        let rendered = head
            .render(azimuth(centre), &piece, f64::from(fs))
            .expect("render");
        for (ear, r) in ears.iter_mut().zip(&rendered) {
            for (k, v) in r.iter().enumerate() {
                if let Some(e) = usize::try_from(at(k)).ok().and_then(|t| ear.get_mut(t)) {
                    *e += v;
                }
            }
        }
    }
    ears
}

/// The talker twice over while the head turns 30 deg to the left during the first pass
/// and back during the second: the signal, its rate, and the yaw track written to a CSV
/// file named after `name`.
struct TurnAndBack {
    x: Vec<f64>,
    fs: u32,
    /// Seconds of one pass.
    half: f64,
    track: PathBuf,
}

impl TurnAndBack {
    fn new(name: &str) -> Self {
        let (once, fs) = talker();
        let x: Vec<f64> = once.iter().chain(&once).copied().collect();
        let half = once.len() as f64 / f64::from(fs);
        let track = tmp(&format!("{name}-yaw.csv"));
        std::fs::write(
            &track,
            format!("t_s,yaw_deg\n0,0\n{half},30\n{},0\n", 2.0 * half),
        )
        .expect("csv");
        TurnAndBack { x, fs, half, track }
    }

    /// The head's yaw at `t` s, deg.
    fn yaw(&self, t: f64) -> f64 {
        30.0 * (1.0 - (t / self.half - 1.0).abs()).max(0.0)
    }
}

#[test]
fn a_turning_head_tells_front_from_back_given_its_yaw() {
    // the head turns 30 deg to the left within the first second and back within the
    // next; a source's front-back image moves by twice the turn in the world while the
    // source stays put. The sphere has no pinnae: alone, 30 and 150 deg sound the same
    // to it, and only the turn can decide.
    let turn = TurnAndBack::new("locate");
    let (x, fs, yaw) = (&turn.x, turn.fs, |t: f64| turn.yaw(t));
    let track = turn.track.to_str().expect("path");
    for name in ["sphere", "kemar"] {
        let head = Head::parse(name).unwrap_or_else(|e| panic!("{e}"));
        let mut pinnae_decide = 0;
        for world in [30.0, 150.0, 210.0, 330.0] {
            let ears = turning_render(&head, world, yaw, x, fs);
            let wav = format!("turning-{name}-{world}");
            let found = located_with(&wav, &ears, fs, &["--head", name, "--head-yaw", track]);
            assert!(
                gap(found, world).abs() <= 5.0,
                "{name}, {world} deg in the world: found {found}"
            );
            // a user who ignores the turn: head-relative azimuths
            let relative = sources_located(&wav, &ears, fs, &["--head", name]);
            if name == "sphere" {
                // its static cues are symmetric front to back: without the turn, the
                // first source's front-back image is reported as well, alike salient
                let image = 180.0 - relative[0];
                assert!(
                    relative[1..].iter().any(|r| gap(*r, image).abs() <= 5.0),
                    "{world} deg without the yaw track: {relative:?}, no front-back image"
                );
            } else if gap(relative[0] + 15.0, world).abs() <= 5.0 {
                // (the head's mean yaw is 15 deg)
                pinnae_decide += 1;
            }
        }
        if name == "kemar" {
            eprintln!("without the yaw track, KEMAR's pinnae decided {pinnae_decide} of 4");
        }
    }
}

/// Two talkers' azimuths, deg: tools/eval_localisation.py's eight chosen pairs and the
/// first eight it draws (lateral angles 40 degrees or more apart), front and back, on
/// one side and on both.
const PAIRS: [(f64, f64); 16] = [
    (20.0, 70.0),
    (330.0, 30.0),
    (60.0, 120.0),
    (250.0, 300.0),
    (0.0, 300.0),
    (45.0, 135.0),
    (200.0, 260.0),
    (90.0, 150.0),
    (185.5, 102.9),
    (234.9, 84.4),
    (243.6, 21.9),
    (200.0, 97.7),
    (316.7, 23.1),
    (81.8, 322.4),
    (314.0, 6.7),
    (254.7, 0.4),
];

#[test]
fn two_talkers_on_kemar_are_both_found_within_10_degrees() {
    // the talker twice over, and beside it the same speech 0.7 s later
    let (once, fs) = talker();
    let first: Vec<f64> = once.iter().chain(&once).copied().collect();
    let mut second = first.clone();
    second.rotate_right((0.7 * f64::from(fs)) as usize);
    let head = Head::parse("kemar").unwrap_or_else(|e| panic!("{e}"));
    let mut missed = Vec::new();
    for (a, b) in PAIRS {
        let ears = together(
            head.render(a, &first, f64::from(fs)).expect("render"),
            head.render(b, &second, f64::from(fs)).expect("render"),
        );
        let options = ["--head", "kemar", "--sources", "2"];
        let found = sources_located(&format!("two-{a}-{b}"), &ears, fs, &options);
        let near = |t: f64| {
            found
                .iter()
                .any(|f| (lateral_deg(*f) - lateral_deg(t)).abs() <= 10.0)
        };
        if !(near(a) && near(b)) {
            missed.push(((a, b), found));
        }
    }
    // the issue asks for both in at least 90 % of the pairs
    assert!(
        missed.len() * 10 <= PAIRS.len(),
        "{} of {} pairs missed (truths, found): {missed:?}",
        missed.len(),
        PAIRS.len()
    );
}

/// `afe locate --json --track` of `ears` with `options`: the last report's tracks as
/// (azimuth, mass), the most probable first.
fn tracked(name: &str, ears: &[Vec<f64>; 2], fs: u32, options: &[&str]) -> Vec<(f64, f64)> {
    let options: Vec<&str> = std::iter::once("--track")
        .chain(options.iter().copied())
        .collect();
    let v = locate_json(&format!("track-{name}"), ears, fs, &options);
    let reports = v["tracked"].as_array().expect("reports");
    assert!(
        reports.len() >= 10,
        "{} reports in 2 s at 6 Hz",
        reports.len()
    );
    let mut last: Vec<(f64, f64)> = reports[reports.len() - 1]["tracks"]
        .as_array()
        .expect("tracks")
        .iter()
        .map(|t| {
            (
                t["azimuth_deg"].as_f64().unwrap_or(f64::NAN),
                t["mass"].as_f64().unwrap_or(0.0),
            )
        })
        .collect();
    last.sort_by(|a, b| b.1.total_cmp(&a.1));
    last
}

#[test]
fn tracking_a_turning_sphere_keeps_the_source_and_drops_its_image() {
    // the sphere's static cues cannot tell 150 deg from 30: still, the tracker keeps
    // both; turning 30 deg and back, the image moves in the world and loses out
    let turn = TurnAndBack::new("track");
    let (x, fs, yaw) = (&turn.x, turn.fs, |t: f64| turn.yaw(t));
    let track = &turn.track;
    let head = Head::parse("sphere").expect("sphere");
    let still = head.render(150.0, x, f64::from(fs)).expect("render");
    let both = tracked("still", &still, fs, &["--head", "sphere"]);
    assert_eq!(both.len(), 2, "still: {both:?}");
    assert!(
        both.iter().any(|t| gap(t.0, 150.0).abs() <= 5.0),
        "{both:?}"
    );
    assert!(both.iter().any(|t| gap(t.0, 30.0).abs() <= 5.0), "{both:?}");
    let ears = turning_render(&head, 150.0, yaw, x, fs);
    let turned = tracked(
        "turning",
        &ears,
        fs,
        &[
            "--head",
            "sphere",
            "--head-yaw",
            track.to_str().expect("path"),
        ],
    );
    assert!(gap(turned[0].0, 150.0).abs() <= 5.0, "turning: {turned:?}");
    assert!(
        turned.iter().skip(1).all(|t| t.1 < 0.5 * turned[0].1),
        "the image is not left behind: {turned:?}"
    );
}

/// The active loop on the sphere, frame by frame: each localiser frame of the talker
/// rendered from 160 deg in the world as the head is turned now, scored, tracked; when the
/// head has held still for a second, the tracks are asked for a turn (Stage C), which the
/// neck makes at its speed. Returns the number of turns made before the likeliest track
/// came within 5 deg of the truth with no image left (`None`: never) and the tracks at the
/// end.
fn active_run(follow: bool) -> (Option<usize>, Vec<afe_spatial::Track>) {
    use afe_spatial::{suggest, Localiser, LocaliserParams, Neck, Tracker, TrackerParams};
    let (once, fs) = talker();
    let x: Vec<f64> = (0..5).flat_map(|_| once.iter().copied()).collect();
    let fs = f64::from(fs);
    let head = Head::parse("sphere").expect("sphere");
    let mut localiser = Localiser::new(&head, fs, &LocaliserParams::default()).expect("design");
    let (w, hop) = (localiser.frame_len(), localiser.hop());
    let mut tracker = Tracker::new(&TrackerParams::default(), hop as f64 / fs).expect("tracker");
    let neck = Neck::default();
    let mut row = vec![0.0; localiser.azimuths_deg().len()];
    let (mut yaw, mut target, mut still_since, mut loudest) = (0.0, 0.0, 0.0, 0.0f64);
    let (mut turns, mut found) = (0, None);
    for k in 0..(x.len() - w) / hop {
        let t = (k * hop + w / 2) as f64 / fs;
        let [l, r] = head
            .render(160.0 - yaw, &x[k * hop..k * hop + w], fs)
            .expect("render");
        let scored = localiser.score(&l, &r, &mut row);
        loudest = loudest.max(scored.energy);
        let active = scored.energy >= loudest * 1e-3;
        tracker.step(t, yaw, localiser.azimuths_deg(), active.then_some(&row[..]));
        let tracks = tracker.tracks();
        let likeliest = tracks.iter().max_by(|a, b| a.mass.total_cmp(&b.mass));
        // the image, where it was with the head still and where the head's yaw puts it
        let image = tracks.iter().any(|t| {
            [20.0, 20.0 + 2.0 * yaw]
                .iter()
                .any(|&at| gap(t.azimuth_deg, at).abs() <= 10.0)
        });
        if found.is_none()
            && !image
            && likeliest.is_some_and(|l| gap(l.azimuth_deg, 160.0).abs() <= 5.0)
        {
            found = Some(turns);
        }
        if yaw != target {
            yaw = neck.step_towards(yaw, target, hop as f64 / fs);
            still_since = t;
        } else if follow && t - still_since >= 1.0 {
            if let Some(s) = suggest(tracks, yaw, &neck) {
                target = s.target_yaw_deg;
                turns += 1;
            }
            still_since = t;
        }
    }
    (found, tracker.tracks().to_vec())
}

#[test]
fn an_active_head_turns_as_asked_and_finds_the_source_behind_it() {
    // 160 deg on the sphere: its image at 20 deg sounds the same, and a still head keeps
    // both; the suggested turns decide it in at most two
    let (still, tracks) = active_run(false);
    assert_eq!(still, None, "a still head told 160 from 20: {tracks:?}");
    assert!(
        tracks.iter().any(|t| gap(t.azimuth_deg, 20.0).abs() <= 5.0),
        "{tracks:?}"
    );
    let (turned, tracks) = active_run(true);
    assert!(
        turned.is_some_and(|n| (1..=2).contains(&n)),
        "{turned:?} turns: {tracks:?}"
    );
}

/// Two talkers (the example's speech, forwards and backwards) walking on the sphere at 20
/// deg/s, one from 0 to 80 deg and the other from 80 to 0 over 4 s, crossing at 2 s.
#[test]
fn two_walking_talkers_keep_their_identities_through_a_crossing() {
    let (once, fs) = talker();
    let forwards: Vec<f64> = (0..4).flat_map(|_| once.iter().copied()).collect();
    let backwards: Vec<f64> = forwards.iter().rev().copied().collect();
    let seconds = forwards.len() as f64 / f64::from(fs);
    let head = Head::parse("sphere").expect("sphere");
    let (a, b) = (|t: f64| 20.0 * t, move |t: f64| 20.0 * (seconds - t));
    let ears = together(
        moving_render(&head, a, &forwards, fs),
        moving_render(&head, b, &backwards, fs),
    );
    let v = locate_json("walkers", &ears, fs, &["--head", "sphere", "--track"]);
    let reports = v["tracked"].as_array().expect("reports");
    // the track nearest each talker at a time, its id and gap
    let nearest = |report: &Value, truth: f64| {
        report["tracks"]
            .as_array()
            .expect("tracks")
            .iter()
            .map(|t| {
                (
                    t["id"].as_u64().unwrap_or(0),
                    gap(t["azimuth_deg"].as_f64().unwrap_or(f64::NAN), truth),
                )
            })
            .min_by(|x, y| x.1.abs().total_cmp(&y.1.abs()))
            .unwrap_or((0, f64::NAN))
    };
    let at = |s: f64| {
        reports
            .iter()
            .min_by(|x, y| {
                let d = |r: &Value| (r["t_s"].as_f64().unwrap_or(f64::NAN) - s).abs();
                d(x).total_cmp(&d(y))
            })
            .expect("a report")
    };
    // 1 s in (40 deg apart, before the crossing), and 3.5 s in (60 deg apart, after it)
    let (before, after) = (at(1.0), at(3.5));
    let t = |r: &Value| r["t_s"].as_f64().unwrap_or(f64::NAN);
    let ids = |r: &Value| {
        let (ia, ga) = nearest(r, a(t(r)));
        let (ib, gb) = nearest(r, b(t(r)));
        assert!(ga.abs() <= 5.0 && gb.abs() <= 5.0, "{r}");
        assert_ne!(ia, ib, "{r}");
        (ia, ib)
    };
    assert_eq!(ids(before), ids(after), "{before}\n{after}");
}

#[test]
fn locate_refuses_what_it_cannot_use_in_one_line() {
    // locate writes no file: nothing may appear here
    let none = tmp("locate-nothing.npz");
    let mono = tmp("locate-mono.wav");
    crate::common::write_wav(&mono, 1, 16000, 16000, crate::common::tone);
    let m = mono.to_str().expect("path");
    assert_clear_error(
        &afe(&["locate", m, "--head", "sphere"]),
        "has 1 channel(s): locating needs two (left ear, right ear)",
        &none,
    );
    let stereo = tmp("locate-stereo.wav");
    crate::common::write_wav(&stereo, 2, 16000, 16000, crate::common::tone);
    let s = stereo.to_str().expect("path");
    assert_clear_error(
        &afe(&["locate", s, "--head", "cube"]),
        "unknown head 'cube': use kemar, sphere:radius=M",
        &none,
    );
    assert_clear_error(
        &afe(&["locate", s, "--head", "sphere:radius=5"]),
        "bad sphere parameter 'radius=5'",
        &none,
    );
    let not_sofa = tmp("locate-not.sofa");
    std::fs::write(&not_sofa, b"not an HDF5 file").expect("write");
    assert_clear_error(
        &afe(&["locate", s, "--head", not_sofa.to_str().expect("path")]),
        "not a SOFA file",
        &none,
    );
    assert_clear_error(
        &afe(&["locate", s, "--head", "sphere", "--sources", "0"]),
        "--sources must be at least 1",
        &none,
    );
    let backwards = tmp("locate-backwards.csv");
    std::fs::write(&backwards, "t_s,yaw_deg\n0,0\n1,10\n0.5,20\n").expect("write");
    assert_clear_error(
        &afe(&[
            "locate",
            s,
            "--head",
            "sphere",
            "--head-yaw",
            backwards.to_str().expect("path"),
        ]),
        "head yaw: point 3 at t_s = 0.5 does not follow t_s = 1: times must increase",
        &none,
    );
    assert_clear_error(
        &afe(&["locate", s, "--head", "sphere", "--head-yaw", "/dev/zero"]),
        "cannot read /dev/zero: larger than 65536 KiB",
        &none,
    );
}

/// A robot's platform descriptor gives `afe locate` its head and its ears: the seed
/// robots' ball (data/platforms/ball-15cm.json: 24414 Hz, a 7.5-cm sphere) finds a talker
/// rendered through that sphere at its rate; a file at another rate or channel count, a
/// yaw track beyond the neck's limits, or `--head` beside `--platform` are refused, one
/// line each.
#[test]
fn a_platform_descriptor_gives_the_head_and_is_checked_against_the_file() {
    let ball = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/platforms/ball-15cm.json");
    let ball = ball.to_str().expect("path");
    let (x, fs) = talker();
    // the talker resampled to the ball's rate by holding samples (it stays a talker)
    let fs_ball = 24414u32;
    let held: Vec<f64> = (0..x.len() * fs_ball as usize / fs as usize)
        .map(|i| x[i * fs as usize / fs_ball as usize])
        .collect();
    let head = Head::parse("sphere:radius=0.075,ears=90").expect("sphere");
    let ears = head
        .render(40.0, &held, f64::from(fs_ball))
        .expect("render");
    let found = located_with("platform-ball", &ears, fs_ball, &["--platform", ball]);
    assert!(
        (lateral_deg(found) - lateral_deg(40.0)).abs() <= 5.0,
        "found {found}"
    );
    let none = tmp("locate-platform-nothing.npz");
    let at_44k = tmp("locate-platform-44k.wav");
    crate::common::write_wav(&at_44k, 2, 44100, 4410, crate::common::tone);
    let w = at_44k.to_str().expect("path");
    assert_clear_error(
        &afe(&["locate", w, "--platform", ball]),
        "captures at 24414 Hz; the source is at 44100 Hz",
        &none,
    );
    // the ball with a third microphone on its top, and a two-channel file
    let text = std::fs::read_to_string(ball).expect("descriptor");
    let mut three: Value = serde_json::from_str(&text).expect("json");
    let extra = serde_json::json!({"channel": 2, "role": "extra", "part": "head",
        "position_m": [0.0, 0.0, 0.075]});
    three["audio"]["channels"]
        .as_array_mut()
        .expect("channels")
        .push(extra);
    let three_path = tmp("locate-platform-3ch.json");
    std::fs::write(&three_path, three.to_string()).expect("write");
    // its ears are found among the three channels of its capture
    let with_top = tmp("locate-platform-3ch.wav");
    {
        let spec = hound::WavSpec {
            channels: 3,
            sample_rate: fs_ball,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut w = hound::WavWriter::create(&with_top, spec).expect("wav");
        for (i, (l, r)) in ears[0].iter().zip(&ears[1]).enumerate() {
            for v in [*l, *r, 0.01 * (i as f64 * 0.37).sin()] {
                w.write_sample(v as f32).expect("sample");
            }
        }
        w.finalize().expect("finalize");
    }
    let three_str = three_path.to_str().expect("path");
    let out = afe(&[
        "locate",
        with_top.to_str().expect("path"),
        "--json",
        "--platform",
        three_str,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).expect("json");
    let az = v["sources"][0]["azimuth_deg"].as_f64().expect("azimuth");
    assert!((lateral_deg(az) - lateral_deg(40.0)).abs() <= 5.0, "{v}");
    let two = tmp("locate-platform-2ch.wav");
    crate::common::write_wav(&two, 2, 24414, 2441, crate::common::tone);
    let two = two.to_str().expect("path");
    assert_clear_error(
        &afe(&[
            "locate",
            two,
            "--platform",
            three_path.to_str().expect("path"),
        ]),
        "declares 3 capture channel(s); the source gives 2",
        &none,
    );
    let far = tmp("locate-platform-far.csv");
    std::fs::write(&far, "t_s,yaw_deg\n0,0\n0.5,150\n").expect("write");
    assert_clear_error(
        &afe(&[
            "locate",
            two,
            "--platform",
            ball,
            "--head-yaw",
            far.to_str().expect("path"),
        ]),
        "the head yaw 150 deg at t_s = 0.5 is beyond",
        &none,
    );
    let out = afe(&["locate", w, "--platform", ball, "--head", "sphere"]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("cannot be used with"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let missing = tmp("locate-platform-missing.json");
    std::fs::write(
        &missing,
        text.replace("sphere:radius=0.075,ears=90", "gone.sofa"),
    )
    .expect("write");
    assert_clear_error(
        &afe(&["locate", w, "--platform", missing.to_str().expect("path")]),
        "gone.sofa does not exist",
        &none,
    );
}

/// The last frame of `afe stream`'s `tracking` output over `wav` with `options`, as
/// (azimuth, resolved) per filled slot, and the head yaw it read, deg.
fn streamed_tracks(source: &str, name: &str, options: &[&str]) -> (Vec<(f64, bool)>, f64) {
    let (tracks, yaws) = streamed_tracking(source, name, options);
    (tracks, *yaws.last().expect("frames"))
}

/// The tracks of the last frame of `afe stream -r tracking` on `source` (azimuth,
/// resolved), and the head's yaw in each frame.
fn streamed_tracking(source: &str, name: &str, options: &[&str]) -> (Vec<(f64, bool)>, Vec<f64>) {
    let out = tmp(&format!("stream-tracking-{name}.npz"));
    let mut args = vec!["stream", "--source", source, "-r", "tracking", "-o"];
    args.push(out.to_str().expect("path"));
    args.extend_from_slice(options);
    let run = afe(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let arrays = crate::common::npz_arrays(&out);
    let (_, shape, data) = arrays
        .iter()
        .find(|(k, _, _)| k.starts_with("tracking"))
        .unwrap_or_else(|| {
            panic!(
                "no tracking output in {:?}",
                arrays.iter().map(|a| &a.0).collect::<Vec<_>>()
            )
        });
    let width = shape[1];
    let last = &data[data.len() - width..];
    // four slots of (id, azimuth, uncertainty, mass, velocity, resolved), then the yaw
    let tracks = last[..24]
        .chunks_exact(6)
        .filter(|s| !s[0].is_nan())
        .map(|s| (s[1], s[5] == 1.0))
        .collect();
    (tracks, data.chunks_exact(width).map(|f| f[24]).collect())
}

#[test]
fn afe_stream_tracks_in_the_world_by_the_head_yaw_it_is_given() {
    // the `tracking` request live: a talker at 150 deg on the sphere, the head turning
    // 30 deg and back; given the yaw track, the stream's tracker resolves the source in
    // the world, and without it the head stays still and nothing is resolved
    let turn = TurnAndBack::new("stream");
    let (x, fs, yaw) = (&turn.x, turn.fs, |t: f64| turn.yaw(t));
    let head = Head::parse("sphere").expect("sphere");
    let ears = turning_render(&head, 150.0, yaw, x, fs);
    let wav = tmp("stream-tracking.wav");
    write_binaural(&wav, &ears, fs);
    let track = turn.track.to_str().expect("path");
    let source = format!("wav:{}", wav.display());
    let (given, yaw_read) = streamed_tracks(&source, "turning", &["--head-yaw", track]);
    assert!(yaw_read.abs() < 1.0, "back at 0 at the end: {yaw_read}");
    let first = given.first().expect("a track");
    assert!(
        gap(first.0, 150.0).abs() <= 5.0 && first.1,
        "the likeliest track resolved at 150 deg: {given:?}"
    );
    let (still, yaw_read) = streamed_tracks(&source, "still", &[]);
    assert_eq!(yaw_read, 0.0);
    assert!(
        still.iter().all(|t| !t.1),
        "resolved with no turn: {still:?}"
    );
    // a yaw track going back in time is refused before the stream starts
    let back = tmp("stream-tracking-back.csv");
    std::fs::write(&back, "t_s,yaw_deg\n0,0\n1,10\n0.5,20\n").expect("csv");
    assert_clear_error(
        &afe(&[
            "stream",
            "--source",
            &source,
            "-r",
            "tracking",
            "--head-yaw",
            back.to_str().expect("path"),
        ]),
        "point 3 at t_s = 0.5 does not follow t_s = 1",
        &tmp("stream-tracking-none.npz"),
    );
}

#[test]
fn a_synthetic_head_turns_reports_its_yaw_and_tells_front_from_back() {
    // synth:...,az=150,turn=30: noise behind the head, which turns to 30 deg and back
    // every 2 s and reports its yaw; the stream's tracker sees it turn and resolves the
    // source in the world, where the same synth with a still head resolves nothing
    let fast = ["--for", "4", "--fast"];
    let turning = "synth:fs=16000,noise=0.1,az=150,turn=30";
    let (tracks, yaws) = streamed_tracking(turning, "synth-turning", &fast);
    let top = yaws.iter().copied().fold(0.0, f64::max);
    assert!((top - 30.0).abs() < 0.5, "the head turned to 30 deg: {top}");
    assert!(
        yaws.last().expect("frames").abs() < 1.0,
        "and back: {yaws:?}"
    );
    let first = tracks.first().expect("a track");
    assert!(
        gap(first.0, 150.0).abs() <= 5.0 && first.1,
        "the likeliest track resolved at 150 deg: {tracks:?}"
    );
    let (still, yaws) = streamed_tracking("synth:fs=16000,noise=0.1,az=150", "synth-still", &fast);
    assert!(
        yaws.iter().all(|y| *y == 0.0),
        "a still head reports no yaw"
    );
    assert!(
        still.iter().all(|t| !t.1),
        "resolved with no turn: {still:?}"
    );
    // the synthetic head reports its own yaw: a track besides it is refused
    let csv = tmp("stream-synth-turning.csv");
    std::fs::write(&csv, "t_s,yaw_deg\n0,0\n1,10\n").expect("csv");
    assert_clear_error(
        &afe(&[
            "stream",
            "--source",
            turning,
            "--for",
            "1",
            "-r",
            "tracking",
            "--head-yaw",
            csv.to_str().expect("path"),
        ]),
        "the synthetic head reports its own yaw",
        &tmp("stream-tracking-synth-none.npz"),
    );
}
