//! rmw_zenoh's names on the wire, as its releases for Jazzy (0.2.x) and Lyrical (0.10.x)
//! write them: a topic's or service's data key, the liveliness tokens by which ROS 2
//! nodes find each other, the QoS in those tokens, an entity's GID and each sample's
//! attachment.

use std::time::{SystemTime, UNIX_EPOCH};

use xxhash_rust::xxh3::xxh3_128;

/// What an entity is, as its token says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The node itself.
    Node,
    /// A publisher (`MP`).
    Publisher,
    /// A service server (`SS`).
    Service,
}

impl Kind {
    fn tag(self) -> &'static str {
        match self {
            Kind::Node => "NN",
            Kind::Publisher => "MP",
            Kind::Service => "SS",
        }
    }
}

/// The QoS a publisher or service offers (history is always keep-last).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Reliable rather than best effort.
    pub reliable: bool,
    /// Transient local (latched: a late subscriber gets the last `depth` samples).
    pub transient_local: bool,
    /// Samples kept.
    pub depth: u32,
}

/// rmw_zenoh's own defaults, which its tokens leave out: reliable, volatile, keep last 42.
const DEFAULT_DEPTH: u32 = 42;

impl Qos {
    /// Reliable, volatile, keep last 10: ROS 2's default for topics and services.
    pub const DEFAULT: Qos = Qos {
        reliable: true,
        transient_local: false,
        depth: 10,
    };
    /// Reliable, transient local, keep last 1: a latched topic.
    pub const LATCHED: Qos = Qos {
        reliable: true,
        transient_local: true,
        depth: 1,
    };

    /// The token's QoS part: `reliability:durability:history,depth:deadline:lifespan:
    /// liveliness`, each left empty where it is rmw_zenoh's default (numbers are rmw's
    /// enums: best effort 2, transient local 1).
    pub fn token(self) -> String {
        let reliability = if self.reliable { "" } else { "2" };
        let durability = if self.transient_local { "1" } else { "" };
        let depth = if self.depth == DEFAULT_DEPTH {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!("{reliability}:{durability}:,{depth}:,:,:,,")
    }
}

/// The node's identity on the ROS graph.
#[derive(Debug, Clone)]
pub struct NodeName {
    /// ROS_DOMAIN_ID.
    pub domain: u32,
    /// Its namespace, `/` or `/robot`.
    pub namespace: String,
    /// Its name, e.g. `afe`.
    pub name: String,
}

/// `/` becomes `%` inside one chunk of a token.
fn mangle(s: &str) -> String {
    s.replace('/', "%")
}

impl NodeName {
    /// A topic's or service's full name: `~/x` and `x` under the node, `/x` as given.
    pub fn resolve(&self, name: &str) -> String {
        let ns = self.namespace.trim_end_matches('/');
        if let Some(rest) = name.strip_prefix("~/") {
            format!("{ns}/{}/{rest}", self.name)
        } else if name.starts_with('/') {
            name.to_string()
        } else {
            format!("{ns}/{name}")
        }
    }

    /// The data key of a topic or service: `<domain>/<name without its outer
    /// slashes>/<DDS type name>/<type hash>`.
    pub fn data_key(&self, full_name: &str, dds_type: &str, hash: &str) -> String {
        format!(
            "{}/{}/{dds_type}/{hash}",
            self.domain,
            full_name.trim_matches('/')
        )
    }

    /// The liveliness token of the node (`entity` = its own id) or of one of its
    /// entities: `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/
    /// <namespace>/<node>[/<name>/<type>/<hash>/<qos>]`, slashes inside a chunk as `%`.
    pub fn token(
        &self,
        zid: &str,
        node_id: u64,
        entity_id: u64,
        kind: Kind,
        topic: Option<(&str, &str, &str, Qos)>,
    ) -> String {
        let mut t = format!(
            "@ros2_lv/{}/{zid}/{node_id}/{entity_id}/{}/%/{}/{}",
            self.domain,
            kind.tag(),
            mangle(&self.namespace),
            mangle(&self.name)
        );
        if let Some((name, dds_type, hash, qos)) = topic {
            t.push_str(&format!(
                "/{}/{}/{}/{}",
                mangle(name),
                mangle(dds_type),
                mangle(hash),
                qos.token()
            ));
        }
        t
    }
}

/// An entity's GID: the 128-bit XXH3 of its token, low half first.
pub fn gid(token: &str) -> [u8; 16] {
    let h = xxh3_128(token.as_bytes());
    let mut g = [0; 16];
    g[..8].copy_from_slice(&(h as u64).to_le_bytes());
    g[8..].copy_from_slice(&((h >> 64) as u64).to_le_bytes());
    g
}

/// Bytes of a sample's attachment.
pub const ATTACHMENT_BYTES: usize = 33;

/// A sample's attachment in zenoh-ext's serialisation: the sequence number and the
/// source time (ns since the Unix epoch) as little-endian i64, then the GID as an array
/// (its length, 16, as a one-byte LEB128, then its bytes).
pub fn attachment(sequence: i64, time_ns: i64, gid: &[u8; 16]) -> [u8; ATTACHMENT_BYTES] {
    let mut a = [0; ATTACHMENT_BYTES];
    a[..8].copy_from_slice(&sequence.to_le_bytes());
    a[8..16].copy_from_slice(&time_ns.to_le_bytes());
    a[16] = 16;
    a[17..].copy_from_slice(gid);
    a
}

/// The sequence number and GID of an attachment (a service call's).
pub fn read_attachment(a: &[u8]) -> Option<(i64, [u8; 16])> {
    if a.len() != ATTACHMENT_BYTES || a[16] != 16 {
        return None;
    }
    let mut seq = [0; 8];
    seq.copy_from_slice(&a[..8]);
    let mut gid = [0; 16];
    gid.copy_from_slice(&a[17..]);
    Some((i64::from_le_bytes(seq), gid))
}

/// Now, in ns since the Unix epoch.
pub fn now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tokens of demo_nodes' listener node and talker's `/chatter` publisher (keep
    /// last 7) as rmw_zenoh's design document (docs/design.md, Jazzy branch) shows them,
    /// and the data key of that topic.
    #[test]
    fn the_design_documents_tokens_and_key_are_built_again() {
        let hash = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";
        let string = "std_msgs::msg::dds_::String_";
        let named = |name: &str| NodeName {
            domain: 0,
            namespace: "/".into(),
            name: name.into(),
        };
        assert_eq!(
            named("listener").token("aac3178e146ba6f1fc6e6a4085e77f21", 0, 0, Kind::Node, None),
            "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
        );
        let talker = named("talker");
        let qos = Qos {
            depth: 7,
            ..Qos::DEFAULT
        };
        let chatter = talker.resolve("chatter");
        assert_eq!(
            talker.token(
                "8b20917502ee955ac4476e0266340d5c",
                0,
                10,
                Kind::Publisher,
                Some((&chatter, string, hash, qos))
            ),
            format!(
                "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/{string}/{hash}/::,7:,:,:,,"
            )
        );
        assert_eq!(
            talker.data_key(&chatter, string, hash),
            format!("0/chatter/{string}/{hash}")
        );
    }

    #[test]
    fn names_resolve_under_the_node_and_its_namespace() {
        let n = NodeName {
            domain: 3,
            namespace: "/robot".into(),
            name: "afe".into(),
        };
        assert_eq!(n.resolve("~/ratemap_left"), "/robot/afe/ratemap_left");
        assert_eq!(n.resolve("audio"), "/robot/audio");
        assert_eq!(n.resolve("/tf"), "/tf");
        assert_eq!(n.data_key("/robot/afe/x", "T", "H"), "3/robot/afe/x/T/H");
        assert_eq!(Qos::LATCHED.token(), ":1:,1:,:,:,,");
        assert_eq!(
            Qos {
                reliable: false,
                transient_local: false,
                depth: 42
            }
            .token(),
            "2::,:,:,:,,"
        );
    }

    #[test]
    fn an_attachment_reads_back_and_a_gid_is_the_tokens() {
        let g = gid("@ros2_lv/0/1f0e/0/0/NN/%/%/talker");
        assert_ne!(g, gid("@ros2_lv/0/1f0e/0/0/NN/%/%/listener"));
        let a = attachment(5, 1_700_000_000_000_000_000, &g);
        assert_eq!(read_attachment(&a), Some((5, g)));
        assert_eq!(read_attachment(&a[..32]), None);
    }
}
