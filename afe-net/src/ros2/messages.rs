//! The node's messages in CDR, field for field as `ros/afe_msgs/` defines them: the
//! frames of an output (`afe_msgs/msg/Signal`), the input (`afe_msgs/msg/Audio`), the
//! platform (`std_msgs/msg/String`), and its services' requests and responses.

use super::cdr::{Malformed, Reader, Writer};

/// A `std_msgs/Header`: the stamp in ns since the Unix epoch, and no frame id.
fn header(w: &mut Writer<'_>, stamp_ns: i64) {
    w.i32(stamp_ns.div_euclid(1_000_000_000) as i32);
    w.u32(stamp_ns.rem_euclid(1_000_000_000) as u32);
    w.string("");
}

/// What an output says of itself, fixed while its request stands.
#[derive(Debug, Clone)]
pub struct Described {
    /// The AFE request.
    pub request: String,
    /// The output, e.g. `ratemap_left`.
    pub output: String,
    /// `time-frequency`, `correlation`, ...
    pub kind: &'static str,
    /// The unit of the values.
    pub unit: &'static str,
    /// The axes of a frame after time.
    pub axes: Vec<&'static str>,
    /// Frames per second, Hz.
    pub sample_rate: f64,
    /// Centre frequencies, Hz.
    pub centre_frequencies: Vec<f64>,
    /// Lags, s.
    pub lags: Vec<f64>,
    /// Feature names.
    pub features: Vec<String>,
    /// The shape of a frame.
    pub frame_shape: Vec<u32>,
    /// Whether values come in (real, imaginary) pairs.
    pub complex: bool,
}

/// Where a block's frames of an output sit in the stream.
#[derive(Debug, Clone, Copy)]
pub struct Placed {
    /// Stamp of the first frame, ns since the Unix epoch.
    pub stamp_ns: i64,
    /// Index of the first frame among the output's.
    pub first_frame: u64,
    /// Input frames the source lost so far.
    pub frames_lost: u64,
    /// Time of the first frame from the stream's start, s.
    pub first_time_s: f64,
}

/// An `afe_msgs/msg/Signal` of `frames` frames of `data`.
pub fn signal(buf: &mut Vec<u8>, d: &Described, at: Placed, frames: usize, data: &[f64]) {
    let mut w = Writer::new(buf);
    header(&mut w, at.stamp_ns);
    w.string(&d.request);
    w.string(&d.output);
    w.string(d.kind);
    w.string(d.unit);
    w.u64(at.first_frame);
    w.u64(at.frames_lost);
    w.f64(d.sample_rate);
    w.f64(at.first_time_s);
    w.strings(d.axes.iter().copied());
    w.f64s(d.centre_frequencies.iter().copied());
    w.f64s(d.lags.iter().copied());
    w.strings(d.features.iter().map(String::as_str));
    w.u32s(d.frame_shape.iter().copied());
    w.u8(u8::from(d.complex));
    w.u32(frames as u32);
    w.f64s(data.iter().copied());
}

/// An `afe_msgs/msg/Audio` of the block `input` (one slice per channel).
pub fn audio(buf: &mut Vec<u8>, at: Placed, sample_rate: f64, input: &[Vec<f64>], frames: usize) {
    let mut w = Writer::new(buf);
    header(&mut w, at.stamp_ns);
    w.u64(at.first_frame);
    w.u64(at.frames_lost);
    w.f64(sample_rate);
    w.u32(input.len() as u32);
    w.u32(frames as u32);
    let interleaved = (0..frames).flat_map(|t| input.iter().map(move |ch| ch[t]));
    w.count(frames * input.len());
    w.f64_elements(interleaved);
}

/// A `std_msgs/msg/String`.
pub fn string(buf: &mut Vec<u8>, text: &str) {
    Writer::new(buf).string(text);
}

/// An AFE parameter by name, its value as JSON text.
pub type Parameter = (String, String);

/// A call to one of the node's services, read from its request.
#[derive(Debug, Clone, PartialEq)]
pub enum Call {
    /// `add_request`: a request name and its parameters.
    Add(String, Vec<Parameter>),
    /// `remove_request`.
    Remove(u64),
    /// `modify_parameter`: request, parameter, value (JSON text).
    Modify(u64, String, String),
    /// `get_signals`.
    Signals,
    /// `get_parameters`.
    Parameters(u64),
}

/// The node's services: name (under the node) and `afe_msgs/srv` type.
pub const SERVICES: [(&str, &str); 5] = [
    ("add_request", "AddRequest"),
    ("remove_request", "RemoveRequest"),
    ("modify_parameter", "ModifyParameter"),
    ("get_signals", "GetSignals"),
    ("get_parameters", "GetParameters"),
];

/// The smallest CDR of an `afe_msgs/Parameter`: two empty strings.
const LEAST_PARAMETER: usize = 10;

/// Reads a request of service `ty` (an `afe_msgs/srv` type).
pub fn read_call(ty: &str, payload: &[u8]) -> Result<Call, Malformed> {
    let mut r = Reader::new(payload)?;
    Ok(match ty {
        "AddRequest" => {
            let name = r.string()?;
            let n = r.count(LEAST_PARAMETER)?;
            let params = (0..n)
                .map(|_| Ok((r.string()?, r.string()?)))
                .collect::<Result<_, Malformed>>()?;
            Call::Add(name, params)
        }
        "RemoveRequest" => Call::Remove(r.u64()?),
        "ModifyParameter" => Call::Modify(r.u64()?, r.string()?, r.string()?),
        "GetSignals" => Call::Signals,
        "GetParameters" => Call::Parameters(r.u64()?),
        _ => return Err(Malformed(format!("no service of type {ty}"))),
    })
}

/// One output as `get_signals` lists it.
#[derive(Debug, Clone)]
pub struct Listed {
    /// The request it belongs to.
    pub request_id: u64,
    /// Its topic's full name.
    pub topic: String,
    /// What it is.
    pub described: Described,
}

/// A service's response.
#[derive(Debug, Clone)]
pub enum Response {
    /// `add_request`'s: the request's id and its outputs' topics.
    Added(u64, Vec<String>),
    /// `remove_request`'s or `modify_parameter`'s success.
    Done,
    /// `get_signals`'s.
    Signals(Vec<Listed>),
    /// `get_parameters`'s.
    Parameters(Vec<Parameter>),
    /// Any service's refusal, with why (`get_signals` never refuses).
    Refused(String),
}

/// The CDR of a response of service `ty`.
pub fn response(ty: &str, r: &Response) -> Vec<u8> {
    let mut buf = Vec::new();
    let mut w = Writer::new(&mut buf);
    let (ok, why) = match r {
        Response::Refused(why) => (false, why.as_str()),
        _ => (true, ""),
    };
    match ty {
        "GetSignals" => {
            let listed = match r {
                Response::Signals(l) => l.as_slice(),
                _ => &[],
            };
            w.count(listed.len());
            for l in listed {
                let d = &l.described;
                w.u64(l.request_id);
                w.string(&d.request);
                w.string(&d.output);
                w.string(&l.topic);
                w.string(d.kind);
                w.string(d.unit);
                w.f64(d.sample_rate);
                w.u32s(d.frame_shape.iter().copied());
            }
        }
        _ => {
            w.u8(u8::from(ok));
            w.string(why);
            match (ty, r) {
                ("AddRequest", Response::Added(id, topics)) => {
                    w.u64(*id);
                    w.strings(topics.iter().map(String::as_str));
                }
                ("AddRequest", _) => {
                    w.u64(0);
                    w.count(0);
                }
                ("GetParameters", Response::Parameters(p)) => {
                    w.count(p.len());
                    for (name, value) in p {
                        w.string(name);
                        w.string(value);
                    }
                }
                ("GetParameters", _) => w.count(0),
                _ => {}
            }
        }
    }
    buf
}

#[cfg(test)]
mod tests {
    use super::*;

    fn add(name: &str, params: &[(&str, &str)]) -> Vec<u8> {
        let mut buf = Vec::new();
        let mut w = Writer::new(&mut buf);
        w.string(name);
        w.count(params.len());
        for (k, v) in params {
            w.string(k);
            w.string(v);
        }
        buf
    }

    #[test]
    fn an_add_request_reads_back_with_its_parameters() {
        let call = read_call("AddRequest", &add("ratemap", &[("fb_nChannels", "16")])).unwrap();
        assert_eq!(
            call,
            Call::Add("ratemap".into(), vec![("fb_nChannels".into(), "16".into())])
        );
    }

    #[test]
    fn a_truncated_or_lying_request_is_malformed() {
        let whole = add("ratemap", &[("fb_nChannels", "16")]);
        for cut in 0..whole.len() {
            assert!(
                read_call("AddRequest", &whole[..cut]).is_err(),
                "cut at {cut}"
            );
        }
        let mut lying = add("ild", &[]);
        let n = lying.len();
        lying[n - 4..].copy_from_slice(&1_000_000u32.to_le_bytes());
        let e = read_call("AddRequest", &lying).unwrap_err();
        assert!(e.0.contains("1000000 elements"), "{}", e.0);
    }

    #[test]
    fn a_refusal_carries_its_reason_in_every_services_response() {
        for (_, ty) in SERVICES {
            let bytes = response(ty, &Response::Refused("no such request".into()));
            let mut r = Reader::new(&bytes).unwrap();
            if ty == "GetSignals" {
                assert_eq!(r.count(1).unwrap(), 0);
            } else {
                assert_eq!(r.u8().unwrap(), 0, "{ty}: success is false");
                assert_eq!(r.string().unwrap(), "no such request", "{ty}");
            }
        }
    }
}
