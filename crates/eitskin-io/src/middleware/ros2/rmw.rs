//! How ROS 2's Zenoh middleware, `rmw_zenoh`, lays a topic out on Zenoh: the key a message is
//! put on, the attachment every message carries, and the liveliness tokens ROS 2's graph is
//! made of (what `ros2 topic list` shows).

use sha2::{Digest, Sha256};

/// A message type: its ROS name and its type hash (REP 2011, `RIHS01_…`, as Jazzy and later
/// give it; checked in the test suite against an independent implementation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageType {
    /// e.g. `sensor_msgs/msg/Image`.
    pub name: &'static str,
    /// e.g. `RIHS01_d31d…`.
    pub hash: &'static str,
}

/// `eitskin_msgs/msg/Touches` (this repository's `ros2/eitskin_msgs`).
pub const TOUCHES: MessageType = MessageType {
    name: "eitskin_msgs/msg/Touches",
    hash: "RIHS01_d20a917ce1fe363610e0ff91235852011eab875a147a0db1530a26c69bce62c1",
};
/// `geometry_msgs/msg/WrenchStamped`.
pub const WRENCH_STAMPED: MessageType = MessageType {
    name: "geometry_msgs/msg/WrenchStamped",
    hash: "RIHS01_8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77",
};
/// `visualization_msgs/msg/MarkerArray`.
pub const MARKER_ARRAY: MessageType = MessageType {
    name: "visualization_msgs/msg/MarkerArray",
    hash: "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf",
};
/// `sensor_msgs/msg/Image`.
pub const IMAGE: MessageType = MessageType {
    name: "sensor_msgs/msg/Image",
    hash: "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
};

impl MessageType {
    /// The name DDS and rmw_zenoh give the type, e.g. `sensor_msgs::msg::dds_::Image_`.
    pub fn dds_name(&self) -> String {
        let mut parts = self.name.rsplitn(2, '/');
        let (short, package) = (parts.next().unwrap_or_default(), parts.next().unwrap_or_default());
        format!("{}::dds_::{short}_", package.replace('/', "::"))
    }
}

/// The key a topic's messages are put on: `DOMAIN/TOPIC/TYPE/HASH`, the topic without its
/// leading and trailing `/`.
pub fn topic_key(domain: u32, topic: &str, kind: &MessageType) -> String {
    format!("{domain}/{}/{}/{}", topic.trim_matches('/'), kind.dds_name(), kind.hash)
}

/// A name in a liveliness token: its `/` written as `%`.
fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// The liveliness token of a node named `node` in namespace `/`, entity `node_id` of Zenoh
/// session `zid`.
pub fn node_token(domain: u32, zid: &str, node_id: u64, node: &str) -> String {
    format!("@ros2_lv/{domain}/{zid}/{node_id}/{node_id}/NN/%/%/{}", mangle(node))
}

/// The QoS of eitskin's publishers as rmw_zenoh writes it in a token: reliable, volatile, keep
/// the last 10 (ROS 2's default profile).
const QOS: &str = "::,10:,:,:,,";

/// The liveliness token of publisher `entity_id` of that node on `topic`.
pub fn publisher_token(
    domain: u32,
    zid: &str,
    node_id: u64,
    entity_id: u64,
    node: &str,
    topic: &str,
    kind: &MessageType,
) -> String {
    format!(
        "@ros2_lv/{domain}/{zid}/{node_id}/{entity_id}/MP/%/%/{}/{}/{}/{}/{QOS}",
        mangle(node),
        mangle(topic),
        mangle(&kind.dds_name()),
        kind.hash
    )
}

/// A publisher's 16-byte id: the first bytes of SHA-256 of its liveliness token (rmw_zenoh
/// hashes the token too; any value unique to the publisher serves).
pub fn gid(token: &str) -> [u8; 16] {
    let digest = Sha256::digest(token.as_bytes());
    std::array::from_fn(|i| digest[i])
}

/// The attachment rmw_zenoh requires on every message, as Zenoh's serializer writes it: the
/// publisher's sequence number (from 1) and source time (ns since the UNIX epoch), each an i64
/// little-endian, then the 16-byte id as a sequence (its length, 16, in one byte).
pub fn attachment(seq: i64, time_ns: i64, gid: &[u8; 16]) -> [u8; 33] {
    let mut bytes = [0u8; 33];
    bytes[..8].copy_from_slice(&seq.to_le_bytes());
    bytes[8..16].copy_from_slice(&time_ns.to_le_bytes());
    bytes[16] = 16;
    bytes[17..].copy_from_slice(gid);
    bytes
}

/// The 4 bytes before a CDR payload: plain CDR, little-endian, no options.
pub const CDR_LE_HEADER: [u8; 4] = [0, 1, 0, 0];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_laid_out_as_rmw_zenoh_lays_them() {
        assert_eq!(IMAGE.dds_name(), "sensor_msgs::msg::dds_::Image_");
        assert_eq!(
            topic_key(0, "/eitskin/skin/image", &IMAGE),
            format!("0/eitskin/skin/image/sensor_msgs::msg::dds_::Image_/{}", IMAGE.hash)
        );
        let token = publisher_token(7, "abc", 1, 3, "eitskin_skin", "/eitskin/skin/touches", &TOUCHES);
        assert_eq!(
            token,
            format!("@ros2_lv/7/abc/1/3/MP/%/%/eitskin_skin/%eitskin%skin%touches/eitskin_msgs::msg::dds_::Touches_/{}/::,10:,:,:,,", TOUCHES.hash)
        );
        assert_eq!(node_token(7, "abc", 1, "eitskin_skin"), "@ros2_lv/7/abc/1/1/NN/%/%/eitskin_skin");
        let a = attachment(1, -2, &gid(&token));
        assert_eq!((&a[..8], &a[8..16], a[16]), (&1i64.to_le_bytes()[..], &(-2i64).to_le_bytes()[..], 16));
    }
}
