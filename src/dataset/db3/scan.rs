//! One pass over a ROS2 bag's `topics` and `messages` tables (the first
//! bytes of each message only: images are placed, not read), gathering what
//! librealsense's ROS2 recorder writes into the ROS1 reader's
//! [`Collected`]:
//!
//! - images: `<stream>/image/data/compressedDepth` (depth) and
//!   `<stream>/image/data/compressed` (colour), `sensor_msgs/CompressedImage`;
//!   each one's time is its frame's `timestamp` (milliseconds) in the
//!   `<stream>/image/metadata` string sent with it (same bag time), else
//!   its header stamp (the recorder's clock, not the camera's);
//! - calibration: `<stream>/camera_info`, a string
//!   `width=..;height=..;fx=..;ppx=..;fy=..;ppy=..;model=..;coeffs=..`
//!   (librealsense's own distortion model name), else the
//!   `sensor_msgs/CameraInfo` at `<stream>/image/camera_info`;
//! - extrinsics: `<stream>/tf/ref_N`, a string `rotation=9 values;translation=3 values`
//!   (`rs2_extrinsics` from the reference stream N, metres), taken as
//!   librealsense's ROS1 writer turns the same values into the `tf/N`
//!   quaternion, so both formats register colour alike;
//! - the depth units option `<sensor>/option/Depth_Units/value` (a string);
//! - IMU samples (`sensor_msgs/Imu`).

use std::collections::HashMap;
use std::io::{Read, Seek};

use glam::{DMat3, DQuat};

use super::cdr::{self, field};
use super::sqlite::{record, Sqlite, Value};
use super::Db3Error;
use crate::dataset::rosbag::{CameraInfo, Collected, ImageHead, Recording};
use crate::dataset::{DatasetError, DatasetKind, Sequence};

/// The most of each message read by the scan, bytes: every message it
/// decodes (strings, camera info, IMU, an image's head and PNG header) is
/// far shorter.
const PREFIX: u64 = 4096;

/// A `.db3` recording: frames placed by the row id of their messages.
pub type Db3Recording = Recording<i64>;

/// What the scan found: the recording and the `messages` table's root page.
pub(crate) struct Scanned {
    pub recording: Db3Recording,
    pub messages_root: u32,
}

/// An image's place and time before its metadata is matched.
struct Pending {
    topic: String,
    bag_time_ns: i64,
    head: ImageHead,
    rowid: i64,
}

/// Where an image topic's PNG starts in a message's data: `compressedDepth`
/// puts a 12-byte ConfigHeader (format, two depth parameters) before it.
pub(crate) fn png_offset(format: &str) -> usize {
    if format.contains("compressedDepth") {
        12
    } else {
        0
    }
}

/// The encoding before compression (`16UC1`, `rgb8`) of a CompressedImage
/// `format`, if the compression is PNG.
pub(crate) fn png_encoding(format: &str, topic: &str) -> Result<String, Db3Error> {
    let (encoding, compression) = format.split_once(';').unwrap_or(("", format));
    if !compression.to_ascii_lowercase().contains("png") {
        return Err(Db3Error::UnsupportedCompression {
            topic: topic.to_owned(),
            format: format.to_owned(),
        });
    }
    Ok(encoding.trim().to_owned())
}

/// An image's head from the first bytes of its CompressedImage message:
/// size from the PNG's IHDR.
fn image_head(bytes: &[u8], topic: &str) -> Result<ImageHead, Db3Error> {
    let head = cdr::compressed_head(bytes, topic)?;
    let encoding = png_encoding(&head.format, topic)?;
    let png = head.data_offset + png_offset(&head.format);
    let ihdr = bytes
        .get(png..png + 24)
        .filter(|b| b.starts_with(b"\x89PNG\r\n\x1a\n") && &b[12..16] == b"IHDR")
        .ok_or_else(|| Db3Error::Message {
            topic: topic.to_owned(),
            reason: format!("no PNG header where its data start ({})", head.format),
        })?;
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    Ok(ImageHead {
        stamp_s: head.stamp_s,
        width: be(&ihdr[16..20]),
        height: be(&ihdr[20..24]),
        encoding,
        big_endian: true,
        step: 0,
        data_offset: png,
        data_len: head.data_len.saturating_sub(png_offset(&head.format)),
    })
}

/// A librealsense `camera_info` string as a camera info.
fn camera_info_string(text: &str) -> Option<CameraInfo> {
    let num = |k: &str| field(text, k)?.parse::<f64>().ok();
    let (fx, fy, cx, cy) = (num("fx")?, num("fy")?, num("ppx")?, num("ppy")?);
    let d = field(text, "coeffs")
        .unwrap_or("")
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse::<f64>().ok())
        .collect::<Option<Vec<f64>>>()?;
    Some(CameraInfo {
        width: field(text, "width")?.parse().ok()?,
        height: field(text, "height")?.parse().ok()?,
        distortion_model: field(text, "model").unwrap_or("").to_owned(),
        d,
        k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
    })
}

/// A `tf/ref_N` string as translation (metres) and rotation `[x, y, z, w]`.
fn transform_string(text: &str) -> Option<([f64; 3], [f64; 4])> {
    let values = |k: &str| -> Option<Vec<f64>> {
        field(text, k)?
            .split(',')
            .map(|s| s.trim().parse::<f64>().ok())
            .collect()
    };
    let r: [f64; 9] = values("rotation")?.try_into().ok()?;
    let t: [f64; 3] = values("translation")?.try_into().ok()?;
    // librealsense's ROS1 writer (rot2quat) reads r[3i + j] as row i,
    // column j: so does this, so that a .db3 and a .bag agree.
    let q = DQuat::from_mat3(&DMat3::from_cols_array(&r).transpose());
    Some((t, [q.x, q.y, q.z, q.w]))
}

/// The stream of a topic (`/device_0/sensor_0/Depth_0`): what comes
/// before `/image/` or `/tf/`, or the topic.
fn stream(topic: &str) -> &str {
    topic
        .rsplit_once("/image/")
        .or_else(|| topic.rsplit_once("/tf/"))
        .map_or(topic, |(s, _)| s)
}

/// Reads the tables once; see the module documentation.
pub(crate) fn scan<R: Read + Seek>(db: &mut Sqlite<R>) -> Result<Scanned, Db3Error> {
    let tables = db.tables()?;
    let root = |name: &'static str| {
        tables
            .iter()
            .find(|t| t.name == name)
            .map(|t| t.root)
            .ok_or_else(|| Db3Error::MissingTable {
                table: name,
                found: tables.iter().map(|t| t.name.clone()).collect(),
            })
    };
    let (topics_root, messages_root) = (root("topics")?, root("messages")?);
    // Topic id -> (name, type); topics serialised otherwise than CDR are left out.
    let mut topics: HashMap<i64, (String, String)> = HashMap::new();
    db.for_each_row(topics_root, PREFIX, |rowid, payload, _| {
        let bad = |reason: String| Db3Error::Message {
            topic: format!("topics row {rowid}"),
            reason,
        };
        let values = record(payload).map_err(bad)?;
        if let [_, Value::Text(name), Value::Text(kind), Value::Text(format), ..] =
            values.as_slice()
        {
            if *format == b"cdr" {
                let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
                topics.insert(rowid, (text(name), text(kind)));
            }
        }
        Ok(())
    })?;
    let mut collected: Collected<i64> = Collected::default();
    let mut pending = Vec::new();
    let mut frame_times: HashMap<(String, i64), f64> = HashMap::new();
    db.for_each_row(messages_root, PREFIX, |rowid, payload, _| {
        let bad = |reason: String| Db3Error::Message {
            topic: format!("messages row {rowid}"),
            reason,
        };
        let values = record(payload).map_err(bad)?;
        let [_, Value::Int(topic_id), Value::Int(bag_time_ns), Value::Blob { bytes, .. }, ..] =
            values.as_slice()
        else {
            return Err(bad("not (id, topic_id, timestamp, data)".to_owned()));
        };
        let Some((topic, kind)) = topics.get(topic_id) else {
            return Ok(());
        };
        visit(&mut collected, topic, kind, bytes, |head| {
            pending.push(Pending {
                topic: topic.clone(),
                bag_time_ns: *bag_time_ns,
                head,
                rowid,
            });
        })
        .map(|frame_time| {
            if let Some(t) = frame_time {
                frame_times.insert((stream(topic).to_owned(), *bag_time_ns), t);
            }
        })
    })?;
    for mut p in pending {
        let key = (stream(&p.topic).to_owned(), p.bag_time_ns);
        if let Some(&t) = frame_times.get(&key) {
            p.head.stamp_s = t;
        }
        collected.add_image(&p.topic, p.head, p.rowid);
    }
    let recording = Recording::from_collected(collected)?;
    Ok(Scanned {
        recording,
        messages_root,
    })
}

/// Keeps what one message says; an image's head goes to `image`; returns
/// a frame's own time (seconds) when the message is an image's metadata.
fn visit(
    c: &mut Collected<i64>,
    topic: &str,
    kind: &str,
    bytes: &[u8],
    image: impl FnOnce(ImageHead),
) -> Result<Option<f64>, Db3Error> {
    match kind {
        "sensor_msgs/msg/CompressedImage" => image(image_head(bytes, topic)?),
        "sensor_msgs/msg/CameraInfo" if !c.has_camera_info(topic) => {
            c.add_camera_info(topic, cdr::camera_info(bytes, topic)?);
        }
        "sensor_msgs/msg/Imu" => {
            let (t, gyro, accel) = cdr::imu(bytes, topic)?;
            c.add_imu(topic, t, gyro, accel);
        }
        "std_msgs/msg/String" => {
            let text = cdr::string(bytes, topic)?;
            if topic.ends_with("/image/metadata") {
                let ms = field(&text, "timestamp").and_then(|v| v.parse::<f64>().ok());
                return Ok(ms.filter(|t| t.is_finite()).map(|t| t * 1e-3));
            }
            if topic.contains("/tf/") {
                if let Some(tf) = transform_string(&text) {
                    c.add_transform(topic, tf);
                }
            } else if topic.ends_with("/camera_info") {
                if let Some(info) = camera_info_string(&text) {
                    // Where the ROS1 reader looks first.
                    let key = format!(
                        "{}/info/camera_info",
                        stream(topic.trim_end_matches("/camera_info"))
                    );
                    c.add_camera_info(&key, info);
                }
            } else if let Ok(units) = text.trim().parse::<f32>() {
                c.add_depth_units(topic, units);
            }
        }
        _ => {}
    }
    Ok(None)
}

/// The sequence of `recording` in the `.db3` `path` (named in its
/// warnings): kind [`DatasetKind::RealSenseDb3`], preset `realsense-d400`,
/// the depth camera's intrinsics, depth scale `1 / depth units`.
#[must_use]
pub fn sequence_of(recording: &Db3Recording, path: &str) -> Sequence {
    let mut sequence = crate::dataset::rosbag::frames_of(recording, DatasetKind::RealSenseDb3);
    sequence.warnings = recording
        .warnings
        .iter()
        .map(|w| DatasetError::Db3 {
            path: path.to_owned(),
            source: Db3Error::Recording(w.clone()),
        })
        .collect();
    sequence
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn librealsense_strings() {
        let info = camera_info_string(
            "width=640;height=480;fx=535.400024;ppx=320.100006;fy=539.200012;ppy=247.600006;model=Brown Conrady;coeffs=0,0,0,0,0",
        )
        .expect("reads");
        assert_eq!((info.width, info.height), (640, 480));
        assert_eq!(info.k[0], 535.400024);
        assert_eq!(info.k[5], 247.600006);
        assert_eq!(info.distortion_model, "Brown Conrady");
        assert_eq!(info.d, vec![0.0; 5]);
        // A quarter turn about z: x goes to y.
        let (t, q) =
            transform_string("rotation=0,-1,0,1,0,0,0,0,1;translation=0.015,0,0").expect("reads");
        assert_eq!(t, [0.015, 0.0, 0.0]);
        let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
        let x = q * glam::DVec3::X;
        assert!((x - glam::DVec3::Y).length() < 1e-12, "{x}");
        assert!(transform_string("rotation=1,0;translation=0,0,0").is_none());
        assert_eq!(
            stream("/device_0/sensor_0/Depth_0/image/metadata"),
            "/device_0/sensor_0/Depth_0"
        );
        assert_eq!(
            stream("/device_0/sensor_0/Depth_0/tf/ref_1"),
            "/device_0/sensor_0/Depth_0"
        );
    }

    #[test]
    fn png_formats() {
        assert_eq!(
            png_encoding("16UC1; compressedDepth png", "t"),
            Ok("16UC1".to_owned())
        );
        assert_eq!(
            png_encoding("rgb8; png compressed bgr8", "t"),
            Ok("rgb8".to_owned())
        );
        assert!(matches!(
            png_encoding("16UC1; compressedDepth rvl", "t"),
            Err(Db3Error::UnsupportedCompression { .. })
        ));
        assert_eq!(png_offset("16UC1; compressedDepth png"), 12);
        assert_eq!(png_offset("rgb8; png compressed bgr8"), 0);
    }
}
