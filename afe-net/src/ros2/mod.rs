//! ROS 2 over rmw_zenoh's protocol, without a ROS installation: the node's interfaces
//! (`ros/afe_msgs/`), their RIHS01 type hashes, CDR, and rmw_zenoh's key expressions,
//! liveliness tokens and attachments as its releases 0.2.10 (Jazzy) and 0.10.5 (Lyrical)
//! write them (`docs/ros2.md`). The server's node itself is `afe serve --ros2`.

pub mod cdr;
pub mod hash;
pub mod idl;
pub mod messages;
pub mod names;

use crate::RemoteError;

/// Who the node is on the ROS graph.
#[derive(Debug, Clone)]
pub struct Ros2Options {
    /// ROS_DOMAIN_ID, 0 to 232.
    pub domain: u32,
    /// The node's namespace, `/` or e.g. `/robot`.
    pub namespace: String,
    /// The node's name.
    pub node: String,
}

impl Default for Ros2Options {
    fn default() -> Self {
        Ros2Options {
            domain: 0,
            namespace: "/".into(),
            node: "afe".into(),
        }
    }
}

/// Whether `s` is a ROS 2 name token: a letter or underscore, then letters, digits and
/// underscores.
fn is_token(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl Ros2Options {
    /// Checks the domain and the names as ROS 2 does.
    pub fn check(&self) -> Result<(), RemoteError> {
        if self.domain > 232 {
            return Err(RemoteError::Options(format!(
                "ROS 2 domain {}: give 0 to 232",
                self.domain
            )));
        }
        if !is_token(&self.node) {
            return Err(RemoteError::Options(format!(
                "ROS 2 node name '{}': give letters, digits and underscores, not starting with a digit",
                self.node
            )));
        }
        let ns = &self.namespace;
        let parts_ok = ns == "/"
            || (ns.starts_with('/') && !ns.ends_with('/') && ns[1..].split('/').all(is_token));
        if !parts_ok {
            return Err(RemoteError::Options(format!(
                "ROS 2 namespace '{ns}': give / or /name[/name...] of letters, digits and underscores"
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_domains_are_checked_as_ros_2_does() {
        assert!(Ros2Options::default().check().is_ok());
        let with = |domain: u32, namespace: &str, node: &str| Ros2Options {
            domain,
            namespace: namespace.into(),
            node: node.into(),
        };
        assert!(with(7, "/robot/head", "afe_2").check().is_ok());
        for bad in [
            with(233, "/", "afe"),
            with(0, "robot", "afe"),
            with(0, "/robot/", "afe"),
            with(0, "/", "2afe"),
            with(0, "/", "a-fe"),
        ] {
            assert!(bad.check().is_err(), "{bad:?}");
        }
    }
}
