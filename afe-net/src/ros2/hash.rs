//! RIHS01 type hashes (REP-2011): the SHA-256 of a type's description (its fields and
//! every type they refer to) in the canonical JSON form, which ROS 2 since Iron puts in
//! every topic's and service's key so that only peers of the same definition match.

use std::collections::BTreeMap;
use std::fmt::Write;

use sha2::{Digest, Sha256};

use super::idl::{Base, Count, Field};

/// `type_description_interfaces/msg/FieldType` of an element type.
fn type_id(base: &Base) -> u32 {
    match base {
        Base::Nested(_) => 1,
        Base::String(None) => 17,
        Base::String(Some(_)) => 21,
        Base::Primitive(p) => match *p {
            "int8" => 2,
            // rosidl reads a `.msg` char as uint8
            "uint8" | "char" => 3,
            "int16" => 4,
            "uint16" => 5,
            "int32" => 6,
            "uint32" => 7,
            "int64" => 8,
            "uint64" => 9,
            "float32" => 10,
            "float64" => 11,
            "bool" => 15,
            "byte" => 16,
            "wstring" => 18,
            _ => 0,
        },
    }
}

/// A field's `type` object in the hashed JSON.
fn field_type(f: &Field) -> String {
    let (offset, capacity) = match f.count {
        Count::One => (0, 0),
        Count::Fixed(n) => (48, n),
        Count::Bounded(n) => (96, n),
        Count::Unbounded => (144, 0),
    };
    let string_capacity = match f.base {
        Base::String(Some(n)) => n,
        _ => 0,
    };
    let nested = match &f.base {
        Base::Nested(n) => n.as_str(),
        _ => "",
    };
    format!(
        "{{\"type_id\": {}, \"capacity\": {capacity}, \"string_capacity\": {string_capacity}, \"nested_type_name\": \"{nested}\"}}",
        type_id(&f.base) + offset
    )
}

/// One type's description: its name and fields.
fn individual(name: &str, fields: &[Field]) -> String {
    let fields: Vec<String> = fields
        .iter()
        .map(|f| format!("{{\"name\": \"{}\", \"type\": {}}}", f.name, field_type(f)))
        .collect();
    format!(
        "{{\"type_name\": \"{name}\", \"fields\": [{}]}}",
        fields.join(", ")
    )
}

/// The types `name` refers to, directly or not, by name.
fn referenced<'a>(
    name: &str,
    types: &'a BTreeMap<String, Vec<Field>>,
    found: &mut BTreeMap<&'a str, &'a [Field]>,
) {
    for f in types.get(name).map(Vec::as_slice).unwrap_or_default() {
        if let Base::Nested(n) = &f.base {
            if let Some((key, fields)) = types.get_key_value(n.as_str()) {
                if found.insert(key, fields).is_none() {
                    referenced(n, types, found);
                }
            }
        }
    }
}

/// The canonical JSON that the hash of type `name` is taken of.
fn hashable(name: &str, types: &BTreeMap<String, Vec<Field>>) -> String {
    let mut found = BTreeMap::new();
    referenced(name, types, &mut found);
    let refs: Vec<String> = found.iter().map(|(n, f)| individual(n, f)).collect();
    format!(
        "{{\"type_description\": {}, \"referenced_type_descriptions\": [{}]}}",
        individual(name, types.get(name).map(Vec::as_slice).unwrap_or_default()),
        refs.join(", ")
    )
}

/// The RIHS01 hash of type `name` as ROS 2 writes it: `RIHS01_` and 64 hex digits.
pub fn rihs01(name: &str, types: &BTreeMap<String, Vec<Field>>) -> String {
    let digest = Sha256::digest(hashable(name, types).as_bytes());
    let mut out = String::from("RIHS01_");
    for b in digest {
        let _ = write!(out, "{b:02x}");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::idl::types;
    use super::*;

    /// std_msgs/msg/String's hash as ROS 2 publishes it (rmw_zenoh's design document
    /// and every `ros2 topic info -v` of a String topic since Iron).
    #[test]
    fn std_msgs_string_hashes_as_ros_2_does() {
        assert_eq!(
            rihs01("std_msgs/msg/String", &types()),
            "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
        );
    }

    /// ServiceEventInfo (a `char[16]` among its fields), which every service's event
    /// type holds: ROS 2's hash (the TYPE_VERSION_HASH of service_msgs' generated code).
    #[test]
    fn service_event_info_hashes_as_ros_2_does() {
        assert_eq!(
            rihs01("service_msgs/msg/ServiceEventInfo", &types()),
            "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
        );
    }

    #[test]
    fn a_changed_field_changes_the_hash() {
        let mut all = types();
        let before = rihs01("afe_msgs/msg/Signal", &all);
        let header = rihs01("std_msgs/msg/Header", &all);
        if let Some(time) = all.get_mut("builtin_interfaces/msg/Time") {
            time[1].base = Base::Primitive("int32");
        }
        assert_ne!(
            rihs01("afe_msgs/msg/Signal", &all),
            before,
            "a referenced type"
        );
        assert_ne!(rihs01("std_msgs/msg/Header", &all), header);
    }
}
