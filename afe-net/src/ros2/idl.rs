//! The ROS 2 interfaces the node speaks, read from the `.msg` and `.srv` files of
//! `ros/afe_msgs/` (the package a ROS user builds with colcon) and from the few public
//! ROS interfaces they use: one definition of each type, from which the type hashes and
//! the DDS type names are derived.

use std::collections::BTreeMap;

/// The package of the node's own interfaces.
pub const PACKAGE: &str = "afe_msgs";

/// The node's messages: name and `.msg` text.
const MESSAGES: [(&str, &str); 4] = [
    ("Audio", include_str!("../../../ros/afe_msgs/msg/Audio.msg")),
    (
        "Parameter",
        include_str!("../../../ros/afe_msgs/msg/Parameter.msg"),
    ),
    (
        "Signal",
        include_str!("../../../ros/afe_msgs/msg/Signal.msg"),
    ),
    (
        "SignalInfo",
        include_str!("../../../ros/afe_msgs/msg/SignalInfo.msg"),
    ),
];

/// The node's services: name and `.srv` text.
const SERVICES: [(&str, &str); 5] = [
    (
        "AddRequest",
        include_str!("../../../ros/afe_msgs/srv/AddRequest.srv"),
    ),
    (
        "GetParameters",
        include_str!("../../../ros/afe_msgs/srv/GetParameters.srv"),
    ),
    (
        "GetSignals",
        include_str!("../../../ros/afe_msgs/srv/GetSignals.srv"),
    ),
    (
        "ModifyParameter",
        include_str!("../../../ros/afe_msgs/srv/ModifyParameter.srv"),
    ),
    (
        "RemoveRequest",
        include_str!("../../../ros/afe_msgs/srv/RemoveRequest.srv"),
    ),
];

/// The public ROS 2 interfaces the node's own refer to (as every distribution since
/// Iron defines them), in `.msg` form.
const PUBLIC: [(&str, &str); 4] = [
    ("builtin_interfaces/msg/Time", "int32 sec\nuint32 nanosec\n"),
    (
        "std_msgs/msg/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    ),
    ("std_msgs/msg/String", "string data\n"),
    (
        "service_msgs/msg/ServiceEventInfo",
        "uint8 event_type\nbuiltin_interfaces/Time stamp\nchar[16] client_gid\nint64 sequence_number\n",
    ),
];

/// A field's element type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Base {
    /// A primitive by its `.msg` name (`uint32`, `float64`, `bool`, ...).
    Primitive(&'static str),
    /// `string`, or `string<=N` with its bound.
    String(Option<u64>),
    /// Another message, by its full name (`std_msgs/msg/Header`).
    Nested(String),
}

/// Whether a field holds one element or several.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Count {
    /// One element.
    One,
    /// `T[N]`: exactly N.
    Fixed(u64),
    /// `T[<=N]`: up to N.
    Bounded(u64),
    /// `T[]`: any number.
    Unbounded,
}

/// One field of a message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// Its name.
    pub name: String,
    /// Its element type.
    pub base: Base,
    /// One element or several.
    pub count: Count,
}

/// The primitives of the `.msg` language.
const PRIMITIVES: [&str; 14] = [
    "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64", "float32", "float64", "wstring",
];

/// Every message type the node's interfaces use, by full name (`pkg/msg/Name`, and the
/// `_Request`, `_Response` and `_Event` types and the service types of `pkg/srv/Name`,
/// whose fields are `request_message`, `response_message` and `event_message`, as
/// rosidl generates them).
pub fn types() -> BTreeMap<String, Vec<Field>> {
    let mut all = BTreeMap::new();
    for (name, text) in PUBLIC {
        let package = name.split('/').next().unwrap_or_default();
        all.insert(name.to_string(), parse_fields(text, package));
    }
    for (name, text) in MESSAGES {
        all.insert(format!("{PACKAGE}/msg/{name}"), parse_fields(text, PACKAGE));
    }
    for (name, text) in SERVICES {
        let (request, response) = text.split_once("\n---").unwrap_or((text, ""));
        let full = format!("{PACKAGE}/srv/{name}");
        let nested = |suffix: &str, count| Field {
            name: suffix.to_lowercase(),
            base: Base::Nested(format!("{full}_{suffix}")),
            count,
        };
        all.insert(format!("{full}_Request"), parse_fields(request, PACKAGE));
        all.insert(format!("{full}_Response"), parse_fields(response, PACKAGE));
        let info = Field {
            name: "info".into(),
            base: Base::Nested("service_msgs/msg/ServiceEventInfo".into()),
            count: Count::One,
        };
        all.insert(
            format!("{full}_Event"),
            vec![
                info,
                nested("Request", Count::Bounded(1)),
                nested("Response", Count::Bounded(1)),
            ],
        );
        let message = |part: &str| Field {
            name: format!("{}_message", part.to_lowercase()),
            base: Base::Nested(format!("{full}_{part}")),
            count: Count::One,
        };
        all.insert(
            full.clone(),
            vec![message("Request"), message("Response"), message("Event")],
        );
    }
    all
}

/// The DDS name of a type, as rmw_zenoh puts it in key expressions:
/// `afe_msgs/msg/Signal` → `afe_msgs::msg::dds_::Signal_`.
pub fn dds_name(full: &str) -> String {
    let mut parts: Vec<&str> = full.split('/').collect();
    let last = parts.pop().unwrap_or_default();
    format!("{}::dds_::{last}_", parts.join("::"))
}

/// The fields of a message's text: one per line of `type name`, comments and constants
/// (`type NAME=value`) left out; an empty message gets rosidl's placeholder field.
fn parse_fields(text: &str, package: &str) -> Vec<Field> {
    let mut fields: Vec<Field> = text
        .lines()
        .filter_map(|line| {
            let code = line.split('#').next().unwrap_or_default().trim();
            let mut words = code.split_whitespace();
            let (ty, name) = (words.next()?, words.next()?);
            // a constant is `type NAME=value` (a bound's `<=` is in the type)
            let constant = code[ty.len()..].contains('=');
            (!constant).then(|| field(ty, name, package))
        })
        .collect();
    if fields.is_empty() {
        fields.push(field(
            "uint8",
            "structure_needs_at_least_one_member",
            package,
        ));
    }
    fields
}

/// One field from its `.msg` type (`float64[]`, `string<=8`, `Header`,
/// `afe_msgs/Parameter[<=4]`) and name.
fn field(ty: &str, name: &str, package: &str) -> Field {
    let (element, count) = match ty.split_once('[') {
        None => (ty, Count::One),
        Some((element, rest)) => {
            let inside = rest.trim_end_matches(']');
            let count = if inside.is_empty() {
                Count::Unbounded
            } else if let Some(n) = inside.strip_prefix("<=") {
                Count::Bounded(n.parse().unwrap_or(0))
            } else {
                Count::Fixed(inside.parse().unwrap_or(0))
            };
            (element, count)
        }
    };
    let base = if let Some(bound) = element.strip_prefix("string") {
        Base::String(bound.strip_prefix("<=").and_then(|n| n.parse().ok()))
    } else if let Some(&p) = PRIMITIVES.iter().find(|&&p| p == element) {
        Base::Primitive(p)
    } else if element == "Header" {
        Base::Nested("std_msgs/msg/Header".into())
    } else if let Some((pkg, msg)) = element.split_once('/') {
        Base::Nested(format!("{pkg}/msg/{msg}"))
    } else {
        Base::Nested(format!("{package}/msg/{element}"))
    };
    Field {
        name: name.to_string(),
        base,
        count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_file_gives_its_fields_without_comments_or_constants() {
        let f = parse_fields(
            "# a comment\nuint8 KIND=3\nHeader header # stamp\nstring<=8 tag\nfloat64[] data\nafe_msgs/Parameter[<=4] p\nchar[16] gid\n",
            "afe_msgs",
        );
        let names: Vec<&str> = f.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["header", "tag", "data", "p", "gid"]);
        assert_eq!(f[0].base, Base::Nested("std_msgs/msg/Header".into()));
        assert_eq!(f[1].base, Base::String(Some(8)));
        assert_eq!(f[2].count, Count::Unbounded);
        assert_eq!(f[3].count, Count::Bounded(4));
        assert_eq!(f[3].base, Base::Nested("afe_msgs/msg/Parameter".into()));
        assert_eq!(f[4].count, Count::Fixed(16));
    }

    #[test]
    fn a_service_gives_its_request_response_event_and_service_types() {
        let all = types();
        let empty = &all["afe_msgs/srv/GetSignals_Request"];
        assert_eq!(empty.len(), 1, "rosidl's placeholder field");
        assert_eq!(empty[0].name, "structure_needs_at_least_one_member");
        let service = &all["afe_msgs/srv/AddRequest"];
        let names: Vec<&str> = service.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(
            names,
            ["request_message", "response_message", "event_message"]
        );
        let event = &all["afe_msgs/srv/AddRequest_Event"];
        assert_eq!(event[1].count, Count::Bounded(1));
        for fields in all.values() {
            for f in fields {
                if let Base::Nested(n) = &f.base {
                    assert!(all.contains_key(n), "{n} is defined");
                }
            }
        }
    }

    #[test]
    fn dds_names_are_rmw_zenohs() {
        assert_eq!(
            dds_name("std_msgs/msg/String"),
            "std_msgs::msg::dds_::String_"
        );
        assert_eq!(
            dds_name("afe_msgs/srv/AddRequest"),
            "afe_msgs::srv::dds_::AddRequest_"
        );
    }
}
