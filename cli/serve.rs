//! `afe serve`: a live source served at real time to the web view and to Zenoh clients.

use std::path::PathBuf;

use afe::bass_source::Pacing;
use afe::stream::StreamJob;

use crate::args::{ServeRequests, Threads};
use crate::error::CliError;
use crate::stream::{stream, StreamRun};

/// `afe serve --source SPEC [--http ADDR] [--listen ENDPOINT]`.
#[derive(clap::Args)]
pub(crate) struct ServeArgs {
    /// wav:FILE (replayed in a loop), synth:SPEC or alsa:DEVICE, as for `afe stream`.
    #[arg(long, value_name = "wav:FILE|synth:SPEC|alsa:DEVICE")]
    source: String,
    #[command(flatten)]
    requests: ServeRequests,
    /// Serve the live web view on this address, e.g. 127.0.0.1:8080 (keep it on
    /// loopback: the page can edit the graph, and it has no authentication).
    #[arg(long, value_name = "ADDR")]
    http: Option<std::net::SocketAddr>,
    /// Also let pages of this origin (`scheme://host[:port]`, e.g. `http://robot.local:8080`)
    /// open the web view's WebSocket, or any origin with * (repeatable). By default only
    /// the page's own origin on an IP address or localhost.
    #[arg(long, value_name = "URL", requires = "http")]
    http_allow_origin: Vec<String>,
    /// Zenoh endpoint the server listens on for remote clients (repeatable); loopback
    /// unless told otherwise.
    #[cfg(feature = "remote")]
    #[arg(long, value_name = "ENDPOINT", default_value = afe_net::DEFAULT_LISTEN)]
    listen: Vec<String>,
    /// The server's name: its Zenoh keys are afe/NAME/...
    #[cfg(feature = "remote")]
    #[arg(long, value_name = "NAME", default_value = afe_net::DEFAULT_NAME)]
    name: String,
    /// Zenoh endpoint to connect to as well (repeatable), e.g. a ROS 2 robot's router,
    /// rmw_zenohd's tcp/localhost:7447.
    #[cfg(feature = "remote")]
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// Be a ROS 2 node too, over rmw_zenoh's protocol (docs/ros2.md): the audio, the
    /// platform and the outputs of the requests its services place, on topics.
    #[cfg(feature = "ros2")]
    #[arg(long)]
    ros2: bool,
    /// The ROS 2 node's name.
    #[cfg(feature = "ros2")]
    #[arg(long, value_name = "NAME", default_value = "afe", requires = "ros2")]
    ros2_node: String,
    /// The ROS 2 node's namespace, e.g. /robot.
    #[cfg(feature = "ros2")]
    #[arg(long, value_name = "NS", default_value = "/", requires = "ros2")]
    ros2_namespace: String,
    /// The ROS 2 domain (0 to 232): ROS_DOMAIN_ID's unless given.
    #[cfg(feature = "ros2")]
    #[arg(long, value_name = "ID", env = "ROS_DOMAIN_ID", default_value_t = 0)]
    ros2_domain: u32,
    /// A Zenoh configuration file (JSON5) to start from, e.g. with user-password
    /// authentication (transport/auth/usrpwd); --listen overrides its endpoints.
    #[cfg(feature = "remote")]
    #[arg(long, value_name = "FILE.json5")]
    zenoh_config: Option<PathBuf>,
    /// Zenoh clients holding subscriptions at once (1 to 1024); a further client is
    /// refused until one leaves.
    #[cfg(feature = "remote")]
    #[arg(long, value_name = "N", default_value_t = afe_net::MAX_CLIENTS as u64,
          value_parser = clap::value_parser!(u64).range(1..=afe_net::MAX_CLIENTS_LIMIT as u64))]
    max_clients: u64,
    /// Subscriptions one Zenoh client may hold (1 to 256).
    #[cfg(feature = "remote")]
    #[arg(long, value_name = "N", default_value_t = afe_net::MAX_SUBSCRIPTIONS as u64,
          value_parser = clap::value_parser!(u64).range(1..=afe_net::MAX_SUBSCRIPTIONS_LIMIT as u64))]
    max_subscriptions: u64,
    /// Block fed to the graph per step, in ms.
    #[arg(long, value_name = "M", default_value_t = 10.0)]
    block_ms: f64,
    /// Stop after SECONDS of audio (default: run until stopped).
    #[arg(long = "for", value_name = "SECONDS")]
    duration: Option<f64>,
    /// ALSA capture rate in Hz (default 44100).
    #[arg(long, value_name = "HZ")]
    rate: Option<u32>,
    #[command(flatten)]
    threads: Threads,
    /// Print the final report as one JSON object (and no status line).
    #[arg(long)]
    json: bool,
    /// The robot's platform descriptor (docs/platform.md): checked against the source
    /// (its channels and rate) before the stream starts, and published in the catalogue
    /// (`afe.connect(...).platform`).
    #[arg(long, value_name = "FILE.json")]
    platform: Option<PathBuf>,
}

impl ServeArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let (requests, params) = self.requests.load()?;
        let platform = self
            .platform
            .as_deref()
            .map(crate::files::read_platform)
            .transpose()?;
        let described = platform
            .as_ref()
            .map(crate::files::platform_json)
            .transpose()?;
        let job = StreamJob {
            requests,
            params,
            block_ms: self.block_ms,
            duration_s: self.duration,
            pacing: Pacing::Realtime,
            // the sequential executor unless --threads says otherwise: at 10-ms blocks it
            // gives remote clients the lowest latency (no hand-offs between threads)
            threads: self.threads.threads.unwrap_or(0),
            looping: self.source.starts_with("wav:"),
            alsa_rate: self.rate.unwrap_or(44_100),
            expect: platform
                .as_ref()
                .map(afe_spatial::Platform::expected_source),
            ..StreamJob::default()
        };
        let run = StreamRun {
            source: &self.source,
            pacing: Some(Pacing::Realtime),
            rate_given: self.rate.is_some(),
            as_json: self.json,
            output: None,
            view: self.http,
            view_origins: self.http_allow_origin,
            platform: described.clone(),
            #[cfg(feature = "remote")]
            serve: Some(afe_net::ServeOptions {
                listen: self.listen,
                name: self.name,
                config_file: self.zenoh_config,
                max_clients: self.max_clients as usize,
                max_subscriptions: self.max_subscriptions as usize,
                max_load: afe_net::MAX_LOAD,
                platform: described,
                head_pose: head_pose_fed(&self.source).then(|| job.head_pose.clone()),
                head_yaw_range_deg: platform.as_ref().map(afe_spatial::Platform::yaw_range_deg),
                connect: self.connect,
                #[cfg(feature = "ros2")]
                ros2: self.ros2.then_some(afe_net::ros2::Ros2Options {
                    domain: self.ros2_domain,
                    namespace: self.ros2_namespace,
                    node: self.ros2_node,
                }),
            }),
            endless: true,
        };
        stream(job, &run)
    }
}

/// Whether the motor controller's yaws on `afe/<name>/head/yaw` feed the stream's head
/// pose: not where the source is a synthetic head that reports its own yaw (said on
/// stderr, so that a controller publishing anyway is not left wondering).
#[cfg(feature = "remote")]
fn head_pose_fed(source: &str) -> bool {
    let turning = source
        .parse::<afe::stream::SourceSpec>()
        .is_ok_and(|s| s.turning_head().is_some());
    if turning {
        eprintln!(
            "the synthetic head reports its own yaw: yaws published on afe/<name>/head/yaw \
             are not listened to"
        );
    }
    !turning
}
