//! `afe subscribe`: a remote server's blocks received and tallied.

use afe::ParamMap;

use crate::args::Requests;
use crate::error::CliError;
use crate::outln;

/// `afe subscribe --connect ENDPOINT -r ...`.
#[derive(clap::Args)]
pub(crate) struct SubscribeArgs {
    /// Zenoh endpoint of the server.
    #[arg(long, value_name = "ENDPOINT", default_value = afe_net::DEFAULT_LISTEN)]
    connect: String,
    /// The server's name, when several answer at the endpoint.
    #[arg(long, value_name = "NAME")]
    name: Option<String>,
    #[command(flatten)]
    requests: Requests,
    /// Stop after SECONDS of the server's audio (default: until the server goes or
    /// Ctrl-C).
    #[arg(long = "for", value_name = "SECONDS")]
    duration: Option<f64>,
    /// Print the report as one JSON object.
    #[arg(long)]
    json: bool,
}

impl SubscribeArgs {
    pub(crate) fn run(self) -> Result<(), CliError> {
        let (requests, params) = self.requests.load()?;
        subscribe(
            &self.connect,
            self.name.as_deref(),
            &requests,
            &params,
            self.duration,
            self.json,
        )
    }
}

/// Receives a subscription's blocks until `duration_s` of audio, the server's departure
/// or Ctrl-C, and prints the tally.
fn subscribe(
    endpoint: &str,
    name: Option<&str>,
    requests: &[String],
    params: &ParamMap,
    duration_s: Option<f64>,
    as_json: bool,
) -> Result<(), CliError> {
    let client = afe_net::Client::connect(endpoint, name)?;
    let list: Vec<(&str, ParamMap)> = requests
        .iter()
        .map(|r| (r.as_str(), params.clone()))
        .collect();
    let mut sub = client.subscribe(&list)?;
    if !as_json {
        eprintln!(
            "subscribed to '{}': {}",
            client.name(),
            sub.keys().join(", ")
        );
    }
    let limit = duration_s.map(|d| (d * client.fs()).round() as u64);
    let mut tally = afe_net::Tally::default();
    while !afe::interrupt::requested() && limit.is_none_or(|l| tally.input_frames() < l) {
        match sub.recv(std::time::Duration::from_millis(200)) {
            Ok(Some(frames)) => tally.add(&frames),
            Ok(None) => {}
            Err(afe_net::RemoteError::ServerGone(_)) => break,
            Err(e) => return Err(e.into()),
        }
    }
    let report = tally.report(&sub);
    if as_json {
        outln!("{report}");
    } else {
        outln!(
            "{} blocks ({:.2} s), {} lost; latency from the server's port p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
            report["messages"],
            tally.input_frames() as f64 / client.fs(),
            report["lost_messages"],
            report["latency_ms_p50"].as_f64().unwrap_or(0.0),
            report["latency_ms_p99"].as_f64().unwrap_or(0.0),
            report["latency_ms_max"].as_f64().unwrap_or(0.0),
        );
    }
    Ok(())
}
