//! What both container targets do with a reader's events.
use std::io::Cursor;

use dem_import::container::{mcap, ros1, Event, StopError};
use dem_import::msg;

/// Which reader (each target uses one).
#[allow(dead_code)]
pub enum Kind {
    Mcap,
    Ros1,
}

/// Run the reader of `kind` over `data`, decoding every message and
/// checking that offsets stay inside the file.
pub fn read(data: &[u8], kind: Kind) {
    let len = data.len() as u64;
    let mut on_event = |e: Event<'_>| match e {
        Event::Message { conn, data } => match conn.msg_type.as_str() {
            "grid_map_msgs/GridMap" => {
                if let Ok(m) = msg::GridMap::decode(data, conn.encoding) {
                    if let Some(l) = m.layer_named("elevation") {
                        let _ = m.at(&l, m.center.x, m.center.y);
                    }
                }
            }
            "tf2_msgs/TFMessage" => {
                let _ = msg::decode_tf(data, conn.encoding);
            }
            "sensor_msgs/JointState" => {
                let _ = msg::decode_joint_state(data, conn.encoding);
            }
            _ => {}
        },
        Event::Skipped { offset, .. } => assert!(offset <= len),
    };
    let mut last = 0;
    let mut on_bytes = |b: u64| {
        assert!(b >= last && b <= len);
        last = b;
    };
    let r = match kind {
        Kind::Mcap => mcap::read_from(Cursor::new(data), len, &mut on_event, &mut on_bytes),
        Kind::Ros1 => ros1::read_from(Cursor::new(data), len, &mut on_event, &mut on_bytes),
    };
    if let Err(StopError::Broken { offset, .. }) = r {
        assert!(offset <= len);
    }
}
