//! `afe stream`: requests run on a live source, with compute time per block against its
//! budget; the machinery `afe serve` runs on too.

use std::io::IsTerminal as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use afe::bass_source::Pacing;
use afe::output::OutputFile;
use afe::stream::{SourceSpec, StreamJob, StreamReport};
use afe::Manager;
use serde_json::{json, Value};

use crate::args::{Requests, Threads};
use crate::error::CliError;
use crate::files::{checked_output, save};
use crate::outln;

/// `afe stream --source SPEC -r ...`.
#[derive(clap::Args)]
pub(crate) struct StreamArgs {
    /// wav:FILE, synth:SPEC (e.g. synth:fs=44100,tone=440,noise=0.1,itd_ms=0.4,
    /// ild_db=-6,seed=1; keys fs, tone, amp, noise, seed, itd_ms, ild_db, silence) or
    /// alsa:DEVICE (e.g. alsa:hw:1,0; see `afe devices`).
    #[arg(long, value_name = "wav:FILE|synth:SPEC|alsa:DEVICE")]
    source: String,
    #[command(flatten)]
    requests: Requests,
    /// Block fed to the graph per step, in ms (round(M·fs/1000) frames): the compute
    /// budget of each block.
    #[arg(long, value_name = "M", default_value_t = 10.0)]
    block_ms: f64,
    /// Stop after SECONDS of audio (required for synth and alsa sources, and with
    /// --loop; a wav file plays once by default).
    #[arg(long = "for", value_name = "SECONDS")]
    duration: Option<f64>,
    /// Publish the source at real time (default for synth and alsa).
    #[arg(long, conflicts_with = "fast")]
    realtime: bool,
    /// As fast as the graph computes (default for wav; with alsa, the device is read
    /// between blocks, in the processing thread).
    #[arg(long)]
    fast: bool,
    /// Replay a wav file from its start again after its end.
    #[arg(long = "loop")]
    looping: bool,
    /// Real-time scheduling (SCHED_FIFO) for the processing threads and locked
    /// memory; says what it could not get (it needs root, or CAP_SYS_NICE and
    /// CAP_IPC_LOCK). Real-time pacing only.
    #[arg(long)]
    rt: bool,
    /// ALSA capture rate in Hz (default 44100).
    #[arg(long, value_name = "HZ")]
    rate: Option<u32>,
    #[command(flatten)]
    threads: Threads,
    /// With -o: also save every intermediate signal.
    #[arg(long)]
    all: bool,
    /// The robot's platform descriptor (docs/platform.md): the source must have its
    /// channels and rate.
    #[arg(long, value_name = "FILE.json")]
    platform: Option<PathBuf>,
    /// The head's yaw over time: a CSV of rows `t_s,yaw_deg` (s of the stream, yaw
    /// positive to the left), which the `tracking` request turns its azimuths into the
    /// world's by (checked against the platform's neck when one is given).
    #[arg(long, value_name = "FILE.csv")]
    head_yaw: Option<PathBuf>,
    /// Print the final report as one JSON object (and no status line).
    #[arg(long)]
    json: bool,
    /// Save what was computed, as `afe extract` does.
    #[arg(short = 'o', long = "output", value_name = "OUT.npz")]
    output: Option<PathBuf>,
    /// Serve the live web view of the stream on this address (e.g. 127.0.0.1:8080).
    #[cfg(feature = "view")]
    #[arg(long, value_name = "ADDR")]
    view: Option<std::net::SocketAddr>,
    /// Also let pages of this origin (`scheme://host[:port]`) open the view's WebSocket, or
    /// any origin with * (repeatable). By default only the page's own origin on an IP
    /// address or localhost.
    #[cfg(feature = "view")]
    #[arg(long, value_name = "URL", requires = "view")]
    view_allow_origin: Vec<String>,
}

impl StreamArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let (requests, params) = self.requests.load()?;
        let platform = self
            .platform
            .as_deref()
            .map(crate::files::read_platform)
            .transpose()?;
        let job = StreamJob {
            requests,
            params,
            block_ms: self.block_ms,
            duration_s: self.duration,
            // --realtime, --fast, or the source's default: set in `stream`
            pacing: Pacing::Fast,
            // under --rt the sequential executor unless --threads says otherwise: at
            // 10-ms blocks it is faster (no hand-offs) and never waits on a wake-up
            threads: match (self.rt, self.threads.threads) {
                (true, None) => 0,
                _ => self.threads.count(),
            },
            record: self.output.is_some(),
            all: self.all,
            looping: self.looping,
            alsa_rate: self.rate.unwrap_or(44_100),
            rt: self.rt,
            expect: platform
                .as_ref()
                .map(afe_spatial::Platform::expected_source),
            ..StreamJob::default()
        };
        if let Some(path) = &self.head_yaw {
            let track = crate::files::read_head_yaw(path)?;
            if let Some(p) = &platform {
                p.check_yaw(&track)?;
            }
            job.head_pose.set_track(track.points())?;
        }
        let pacing = match (self.realtime, self.fast) {
            (true, _) => Some(Pacing::Realtime),
            (_, true) => Some(Pacing::Fast),
            _ => None,
        };
        let run = StreamRun {
            source: &self.source,
            pacing,
            rate_given: self.rate.is_some(),
            as_json: self.json,
            output: self.output.as_deref(),
            #[cfg(feature = "view")]
            view: self.view,
            #[cfg(feature = "view")]
            view_origins: self.view_allow_origin,
            #[cfg(feature = "view")]
            platform: platform
                .as_ref()
                .map(crate::files::platform_json)
                .transpose()?,
            #[cfg(feature = "remote")]
            serve: None,
            endless: false,
        };
        stream(job, &run)
    }
}

/// How `afe stream` and `afe serve` run a stream, beyond its job.
pub(crate) struct StreamRun<'a> {
    pub(crate) source: &'a str,
    /// `--realtime` or `--fast` if given.
    pub(crate) pacing: Option<Pacing>,
    pub(crate) rate_given: bool,
    pub(crate) as_json: bool,
    pub(crate) output: Option<&'a Path>,
    /// Serve the live view on this address.
    #[cfg(feature = "view")]
    pub(crate) view: Option<std::net::SocketAddr>,
    /// Origins allowed to open the live view's WebSocket besides the page's own.
    #[cfg(feature = "view")]
    pub(crate) view_origins: Vec<String>,
    /// The robot's platform descriptor, shown on the live view's page.
    #[cfg(feature = "view")]
    pub(crate) platform: Option<serde_json::Value>,
    /// Serve the stream to remote clients over Zenoh.
    #[cfg(feature = "remote")]
    pub(crate) serve: Option<afe_net::ServeOptions>,
    /// Runs until stopped (`afe serve`): no `--for` needed.
    pub(crate) endless: bool,
}

/// What sees each block of a CLI stream: the status line, and the live view's tap.
struct CliObserver<'a> {
    status: &'a mut Status,
    #[cfg(feature = "view")]
    tap: Option<afe_view::Tap>,
    #[cfg(feature = "remote")]
    remote: Option<afe_net::ServeTap>,
}

impl afe::stream::Observer for CliObserver<'_> {
    fn block(&mut self, timing: &afe::stream::Timing, mgr: &mut Manager, input: &[Vec<f64>]) {
        self.status.update(timing);
        #[cfg(feature = "view")]
        if let Some(tap) = &mut self.tap {
            tap.block(timing, mgr, input);
        }
        #[cfg(feature = "remote")]
        if let Some(tap) = &mut self.remote {
            tap.block(timing, mgr, input);
        }
        #[cfg(not(feature = "view"))]
        let _ = (mgr, input);
    }
}

pub(crate) fn stream(mut job: StreamJob, run: &StreamRun<'_>) -> Result<(), CliError> {
    let spec: SourceSpec = run.source.parse()?;
    check_source(&spec, &job, run)?;
    let output = match (run.output, &spec) {
        (Some(o), SourceSpec::Wav(input)) => Some(checked_output(o, input)?),
        (Some(o), _) => Some(OutputFile::check(o)?),
        (None, _) => None,
    };
    job.pacing = run.pacing.unwrap_or_else(|| spec.default_pacing());
    #[cfg(feature = "view")]
    let (view, tap) = start_view(run, job.block_ms)?.unzip();
    #[cfg(feature = "remote")]
    let (server, remote) = start_server(run)?.unzip();
    // measured before the stream, whose thread `--rt` leaves at real-time priority
    let host = afe::host::Host::detect();
    let mut status = Status::new(!run.as_json && std::io::stderr().is_terminal());
    let observer = CliObserver {
        status: &mut status,
        #[cfg(feature = "view")]
        tap,
        #[cfg(feature = "remote")]
        remote,
    };
    // the tap goes with the observer at the end of the stream: pages are told
    #[cfg(feature = "remote")]
    let out = afe_net::run_spec(&spec, &job, observer)?;
    #[cfg(not(feature = "remote"))]
    let out = afe::stream::run_spec(&spec, &job, observer)?;
    status.finish();
    #[cfg(feature = "view")]
    drop(view);
    #[cfg(feature = "remote")]
    drop(server);
    if let Some(path) = &output {
        save(&out.recorded, path)?;
    }
    print_report(&out.report, &job, run, &host)
}

/// Refuses a source that the run's options do not fit: one that never ends without
/// `--for`, `--loop` beyond wav files, `--rate` beyond ALSA.
fn check_source(spec: &SourceSpec, job: &StreamJob, run: &StreamRun<'_>) -> Result<(), CliError> {
    let source = run.source;
    match spec {
        SourceSpec::Wav(_) if job.looping && job.duration_s.is_none() && !run.endless => {
            Err("--loop replays the file forever: give --for SECONDS".into())
        }
        SourceSpec::Synth(_) | SourceSpec::Alsa(_) if job.duration_s.is_none() && !run.endless => {
            Err(format!("'{source}' never ends: give --for SECONDS").into())
        }
        SourceSpec::Synth(_) | SourceSpec::Alsa(_) | SourceSpec::Zenoh { .. } if job.looping => {
            Err("--loop replays wav files only".into())
        }
        SourceSpec::Wav(_) | SourceSpec::Synth(_) | SourceSpec::Zenoh { .. } if run.rate_given => {
            Err(
                "--rate sets the ALSA capture rate (synth: fs= in the spec; wav: the file's rate; zenoh: the server's)"
                    .into(),
            )
        }
        _ => Ok(()),
    }
}

/// The live view the run asks for (`--view`), started, with its tap; a warning where it
/// is open to the network.
#[cfg(feature = "view")]
fn start_view(
    run: &StreamRun<'_>,
    block_ms: f64,
) -> Result<Option<(afe_view::View, afe_view::Tap)>, CliError> {
    let Some(addr) = run.view else {
        return Ok(None);
    };
    let options = afe_view::ViewOptions {
        origins: afe_view::AllowedOrigins::parse(&run.view_origins)
            .map_err(afe_view::ViewError::from)?,
        limits: afe_view::Limits::default(),
        platform: run.platform.clone(),
    };
    let (view, tap) = afe_view::View::start(addr, block_ms, &options)?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "warning: the live view on {addr} is open to the network, without \
             authentication: anyone reaching it can edit the graph"
        );
    }
    eprintln!("live view: http://{}/", view.addr());
    Ok(Some((view, tap)))
}

/// The Zenoh server the run asks for (`afe serve`), started, with its tap; a warning for
/// each endpoint open to the network without authentication.
#[cfg(feature = "remote")]
fn start_server(
    run: &StreamRun<'_>,
) -> Result<Option<(afe_net::Server, afe_net::ServeTap)>, CliError> {
    let Some(options) = &run.serve else {
        return Ok(None);
    };
    let (server, tap) = afe_net::Server::start(options)?;
    for endpoint in options.listen.iter().filter(|e| !afe_net::is_loopback(e)) {
        if !server.authenticated() {
            eprintln!(
                "warning: Zenoh listens on {endpoint}, open to the network, without \
                 authentication: anyone reaching it can subscribe (give --zenoh-config \
                 with transport/auth/usrpwd)"
            );
        }
    }
    eprintln!(
        "zenoh: '{}' on {}",
        server.name(),
        options.listen.join(", ")
    );
    Ok(Some((server, tap)))
}

/// The stream's final report: one JSON object with `--json`, else a line; and how
/// `--rt` went, on stderr.
fn print_report(
    r: &StreamReport,
    job: &StreamJob,
    run: &StreamRun<'_>,
    host: &afe::host::Host,
) -> Result<(), CliError> {
    if let Some(rt) = &r.realtime {
        if rt.complete() {
            eprintln!("real time: {}", rt.describe());
        } else {
            eprintln!("warning: --rt: {}", rt.describe());
        }
    }
    if run.as_json {
        let mut result = serde_json::to_value(r).map_err(|e| e.to_string())?;
        let extra = json!({
            "source": run.source,
            "requests": job.requests,
            "pacing": if job.pacing == Pacing::Realtime { "realtime" } else { "fast" },
            "threads": job.threads,
            "seconds": r.frames as f64 / r.fs,
            "rt": r.realtime.as_ref().map(afe::realtime::Realtime::describe),
            "rt_complete": r.realtime.as_ref().map(afe::realtime::Realtime::complete),
            "host": host,
        });
        if let (Some(all), Value::Object(extra)) = (result.as_object_mut(), extra) {
            all.extend(extra);
        }
        outln!("{result}");
        return Ok(());
    }
    let missed = match r.missed_blocks.as_slice() {
        [] => String::new(),
        m => format!(
            " (blocks {}{})",
            m.iter().map(u64::to_string).collect::<Vec<_>>().join(", "),
            if r.deadline_misses > m.len() as u64 {
                ", ..."
            } else {
                ""
            }
        ),
    };
    let overruns = if r.device_overruns > 0 {
        format!("; {} device overrun(s)", r.device_overruns)
    } else {
        String::new()
    };
    let interrupted = if r.interrupted {
        "; interrupted: what was computed until then is reported (and saved with -o)"
    } else {
        ""
    };
    outln!(
        "{} frames ({:.2} s at {} Hz) in {} blocks of {} frames: compute per block p50 {:.3} ms, \
         p99 {:.3} ms, max {:.3} ms (block {}), budget {:.2} ms ({:.1}x real time on {}); \
         {} deadline miss(es){missed}; {} frame(s) lost{overruns}{interrupted}",
        r.frames,
        r.frames as f64 / r.fs,
        r.fs,
        r.blocks,
        r.block_frames,
        r.compute_ms_p50,
        r.compute_ms_p99,
        r.compute_ms_max,
        r.slowest_block,
        r.budget_ms,
        r.x_realtime,
        host.describe(),
        r.deadline_misses,
        r.lost_frames,
    );
    Ok(())
}

/// The status line of `afe stream` on a terminal: rewritten in place at most 4 times a
/// second.
struct Status {
    shown: bool,
    enabled: bool,
    last: Option<Instant>,
}

impl Status {
    const PERIOD: Duration = Duration::from_millis(250);

    fn new(enabled: bool) -> Self {
        Status {
            shown: false,
            enabled,
            last: None,
        }
    }

    fn update(&mut self, timing: &afe::stream::Timing) {
        if !self.enabled || self.last.is_some_and(|t| t.elapsed() < Self::PERIOD) {
            return;
        }
        self.last = Some(Instant::now());
        self.shown = true;
        eprint!("\r{}\x1b[K", status_line(&timing.report()));
    }

    fn finish(&self) {
        if self.shown {
            eprintln!();
        }
    }
}

fn status_line(r: &StreamReport) -> String {
    format!(
        "{} frames ({:.1} s) | {:.1}x real time | compute p50 {:.2} ms p99 {:.2} ms / {:.2} ms | misses {} | lost {}",
        r.frames,
        r.frames as f64 / r.fs,
        r.x_realtime,
        r.compute_ms_p50,
        r.compute_ms_p99,
        r.budget_ms,
        r.deadline_misses,
        r.lost_frames
    )
}
