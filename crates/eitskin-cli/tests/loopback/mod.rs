//! Zenoh on loopback for the flow tests: a free port on 127.0.0.1, and the test's own peer
//! listening there only, without multicast.
// Each test binary uses a subset of these helpers.
#![allow(dead_code)]

use zenoh::Wait;

/// A free port on loopback (released for the peer to take).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// The test's Zenoh peer, listening on 127.0.0.1:`port` only, without multicast.
pub fn peer(port: u16) -> zenoh::Session {
    let mut config = zenoh::Config::default();
    config.insert_json5("listen/endpoints", &format!("[\"tcp/127.0.0.1:{port}\"]")).unwrap();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    zenoh::open(config).wait().unwrap()
}
