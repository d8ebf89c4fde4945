//! A small ROS1 bag (format 2.0) writer for tests: records, chunks
//! (`none`, `lz4` frames, or a named compression with the bytes as they
//! are), connections, the index's connection records, and the messages a
//! RealSense recording holds (`sensor_msgs/Image`, `CameraInfo`, `Imu`,
//! `geometry_msgs/Transform`, `std_msgs/Float32`), little-endian.

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::Write;

/// One record: header fields, then data.
pub fn record(fields: &[(&str, Vec<u8>)], data: &[u8]) -> Vec<u8> {
    let mut header = Vec::new();
    for (name, value) in fields {
        header.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
        header.extend(name.as_bytes());
        header.push(b'=');
        header.extend(value);
    }
    let mut out = (header.len() as u32).to_le_bytes().to_vec();
    out.extend(header);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
    out
}

/// A bag being written: connections by id (topic, type).
pub struct Bag {
    pub connections: Vec<(String, String)>,
    body: Vec<u8>,
    pub compression: &'static str,
}

impl Bag {
    pub fn new(compression: &'static str) -> Self {
        Self {
            connections: Vec::new(),
            body: Vec::new(),
            compression,
        }
    }

    fn connection_record(&self, id: u32) -> Vec<u8> {
        let (topic, ty) = &self.connections[id as usize];
        let data = record(
            &[
                ("topic", topic.as_bytes().to_vec()),
                ("type", ty.as_bytes().to_vec()),
                ("md5sum", b"*".to_vec()),
                ("message_definition", b"".to_vec()),
            ],
            &[],
        );
        // A connection's data is a header only (no data length after it).
        let data = data[4..data.len() - 4].to_vec();
        record(
            &[
                ("op", vec![0x07]),
                ("conn", id.to_le_bytes().to_vec()),
                ("topic", topic.as_bytes().to_vec()),
            ],
            &data,
        )
    }

    /// Writes one chunk holding `messages` (topic, type, stamp ns, bytes);
    /// each topic's connection is defined in the first chunk that uses it.
    pub fn chunk(&mut self, messages: &[(&str, &str, u64, Vec<u8>)]) {
        let mut inner = Vec::new();
        for (topic, ty, time, bytes) in messages {
            let id = match self.connections.iter().position(|(t, _)| t == topic) {
                Some(i) => i as u32,
                None => {
                    self.connections
                        .push(((*topic).to_owned(), (*ty).to_owned()));
                    let id = (self.connections.len() - 1) as u32;
                    inner.extend(self.connection_record(id));
                    id
                }
            };
            let t = ((time % 1_000_000_000) << 32) | (time / 1_000_000_000);
            inner.extend(record(
                &[
                    ("op", vec![0x02]),
                    ("conn", id.to_le_bytes().to_vec()),
                    ("time", t.to_le_bytes().to_vec()),
                ],
                bytes,
            ));
        }
        let data = match self.compression {
            "lz4" => {
                let mut e = lz4_flex::frame::FrameEncoder::new(Vec::new());
                e.write_all(&inner).unwrap();
                e.finish().unwrap()
            }
            _ => inner.clone(),
        };
        self.body.extend(record(
            &[
                ("op", vec![0x05]),
                ("compression", self.compression.as_bytes().to_vec()),
                ("size", (inner.len() as u32).to_le_bytes().to_vec()),
            ],
            &data,
        ));
    }

    /// The whole file: magic, bag header (padded to 4096 bytes as rosbag
    /// does), chunks, then (when `finished`) the index's connection records.
    pub fn finish(&self, finished: bool) -> Vec<u8> {
        let header_len = 4096 + 13;
        let index_pos = if finished {
            (header_len + self.body.len()) as u64
        } else {
            0
        };
        let fields = [
            ("op", vec![0x03]),
            ("index_pos", index_pos.to_le_bytes().to_vec()),
            (
                "conn_count",
                (self.connections.len() as u32).to_le_bytes().to_vec(),
            ),
            ("chunk_count", 1u32.to_le_bytes().to_vec()),
        ];
        let mut head = record(&fields, &[]);
        let pad = 4096 - head.len();
        head = record(&fields, &vec![b' '; pad]);
        let mut out = b"#ROSBAG V2.0\n".to_vec();
        out.extend(head);
        assert_eq!(out.len(), header_len);
        out.extend(&self.body);
        if finished {
            for id in 0..self.connections.len() as u32 {
                out.extend(self.connection_record(id));
            }
        }
        out
    }
}

fn header(stamp_ns: u64) -> Vec<u8> {
    let mut b = 0u32.to_le_bytes().to_vec();
    b.extend(((stamp_ns / 1_000_000_000) as u32).to_le_bytes());
    b.extend(((stamp_ns % 1_000_000_000) as u32).to_le_bytes());
    b.extend(1u32.to_le_bytes());
    b.push(b'0');
    b
}

fn string(s: &str) -> Vec<u8> {
    let mut b = (s.len() as u32).to_le_bytes().to_vec();
    b.extend(s.as_bytes());
    b
}

/// A `sensor_msgs/Image`.
pub fn image(stamp_ns: u64, width: u32, height: u32, encoding: &str, pixels: &[u8]) -> Vec<u8> {
    let mut b = header(stamp_ns);
    b.extend(height.to_le_bytes());
    b.extend(width.to_le_bytes());
    b.extend(string(encoding));
    b.push(0);
    b.extend(((pixels.len() / height as usize) as u32).to_le_bytes());
    b.extend((pixels.len() as u32).to_le_bytes());
    b.extend(pixels);
    b
}

/// A `sensor_msgs/CameraInfo` (K from fx, fy, cx, cy; R, P, the rest zero).
pub fn camera_info(width: u32, height: u32, model: &str, d: &[f64], k: [f64; 4]) -> Vec<u8> {
    let mut b = header(0);
    b.extend(height.to_le_bytes());
    b.extend(width.to_le_bytes());
    b.extend(string(model));
    b.extend((d.len() as u32).to_le_bytes());
    for v in d {
        b.extend(v.to_le_bytes());
    }
    let [fx, fy, cx, cy] = k;
    for v in [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    for _ in 0..21 {
        b.extend(0f64.to_le_bytes());
    }
    b.extend([0u8; 4 * 6 + 1]);
    b
}

/// A `geometry_msgs/Transform`: translation, quaternion `[x, y, z, w]`.
pub fn transform(t: [f64; 3], q: [f64; 4]) -> Vec<u8> {
    t.iter().chain(&q).flat_map(|v| v.to_le_bytes()).collect()
}

/// A `std_msgs/Float32`.
pub fn float32(v: f32) -> Vec<u8> {
    v.to_le_bytes().to_vec()
}

/// A `sensor_msgs/Imu`: gyro (rad/s), accel (m/s^2).
pub fn imu(stamp_ns: u64, gyro: [f64; 3], accel: [f64; 3]) -> Vec<u8> {
    let mut b = header(stamp_ns);
    let zeros = |n: usize| vec![0u8; 8 * n];
    b.extend(zeros(4 + 9));
    b.extend(gyro.iter().flat_map(|v| v.to_le_bytes()));
    b.extend(zeros(9));
    b.extend(accel.iter().flat_map(|v| v.to_le_bytes()));
    b.extend(zeros(9));
    b
}
